"""The default effort's weighing of the alternatives (bandelets.codec.piece, ``_cheapest``): its wavelet
files decoded from the bins the encoder coded are what the decoder makes of them."""

from __future__ import annotations

import numpy as np

import bandelets
from bandelets.codec import piece
from bandelets.codec.decoder import decode_parsed
from bandelets.format.header import unpack
from bandelets.samples import bevel_normal_map


def test_the_weighed_files_decode_from_their_bins_as_the_decoder_decodes_them(monkeypatch):
    checked = []
    unrestored = piece._PieceEncoder.unrestored

    def compared(self, encoded):
        out = unrestored(self, encoded)
        header, streams = unpack(encoded.data)
        checked.append(np.array_equal(out, decode_parsed(header, streams, restore=False)))
        return out

    monkeypatch.setattr(piece._PieceEncoder, "unrestored", compared)
    x = bevel_normal_map(256)
    data = bandelets.encode(x, bpp=0.25, kind="normal-map")
    assert checked and all(checked)  # a rate target that weighed alternatives, each file the same
    assert bandelets.decode(data).shape == x.shape
