"""What the decoder does after dequantization: the restoration of sparser gradients consistent with the
file's bins (:mod:`.restoration`) and the loop filter the file carries (:mod:`.loopfilter`)."""
