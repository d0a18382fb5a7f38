"""The encoder's search, never imported by the decoder: the Lagrangian of a square (step 8,
:mod:`.lagrangian`), the best quadtrees and the forward transform in the best basis (step 10,
:mod:`.basis`), the direction fields of the lifting (:mod:`.directions`), the count of wavelet levels
(:mod:`.levelchoice`), the loop filter's fit (:mod:`.filterfit`) and the threshold of a target
(:mod:`.ratecontrol`)."""
