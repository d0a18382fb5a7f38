"""Entropy coding (the paper's step 11): the binary range coder (:mod:`.rangecoder`), the context models of
the coefficients (:mod:`.coefficients`), of the coarse approximation (:mod:`.approximation`), of the
quadtrees and directions (:mod:`.trees`, :mod:`.squarecontexts`), the coding order (:mod:`.order`), a
whole image's three streams (:mod:`.image`) and the lossless coder of integer samples (:mod:`.lossless`)."""
