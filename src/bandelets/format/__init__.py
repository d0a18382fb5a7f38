"""The .bdl file format, the bottom floor: the header and its fields (:mod:`.header`), the tiled container
(:mod:`.container`), the quantizer's bins that a file's indices mean (:mod:`.quantizer`), integer samples of a
depth (:mod:`.samples`), the limits a decoder enforces (:mod:`.limits`) and the checks at the door
(:mod:`.checks`). Nothing here imports the rest of the package."""
