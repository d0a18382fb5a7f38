"""The codec: ``encode(array) -> bytes`` (:mod:`.encoder`), ``decode(bytes) -> array`` and
``check(bytes)`` (:mod:`.decoder`), their options (:mod:`.options`), what a normal map's array means
(:mod:`.normalmaps`) and large images in tiles (:mod:`.tiles`). The decoder's modules never import the
encoder's."""
