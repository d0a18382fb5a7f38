"""The applications on top of the codec: the command line (:mod:`.cli`), batches on Dask (:mod:`.batch`),
rate-distortion curves against other codecs (:mod:`.rd`, :mod:`.anchors`, :mod:`.plots`), the demo, the
figure of a file's geometry (:mod:`.show`) and the one-line summaries (:mod:`.summary`)."""
