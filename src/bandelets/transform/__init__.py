"""The transforms of the paper (Peyre and Mallat 2005, section 4), given their geometry: the 2D wavelet
transform (step 2, :mod:`.wavelets`, compiled passes in :mod:`.lifting`), the direction-adaptive lifting of
the finest levels (:mod:`.directional`, not in the paper), the directions of a square (steps 4-5,
:mod:`.geometry`), the quadtree of squares (:mod:`.quadtree`), the bandeletization of a square (steps 5-7
and 9,
:mod:`.bandeletize`), a whole image's bandelet transform for given quadtrees (:mod:`.bandelets`), local frames
of geometry images (section 6, :mod:`.frames`), the Riesz pair of a normal map (:mod:`.riesz`) and the unit
vectors of normal maps (:mod:`.normals`). The choice of the geometry is the encoder's search
(:mod:`bandelets.search`)."""
