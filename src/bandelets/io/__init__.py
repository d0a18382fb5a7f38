"""Files outside the codec: PNG, TIFF, OpenEXR and .npy arrays (:mod:`.files`, :mod:`.floatformats`) and
the imageio plugin for .bdl files (:mod:`.imageio_plugin`)."""
