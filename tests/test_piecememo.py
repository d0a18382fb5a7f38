"""A tile's later passes reuse the directions and geometry of its first (bandelets.codec.piecememo)."""

from __future__ import annotations

import bandelets
from bandelets.codec import piece
from bandelets.codec.options import EncodeOptions
from bandelets.codec.piece import encode_piece
from bandelets.codec.piecememo import PieceMemo
from bandelets.format import container
from bandelets.samples import crease_normal_map


def test_a_later_encode_near_the_first_reuses_its_directions_and_trees(monkeypatch):
    calls = []
    lifted = piece.lifted
    monkeypatch.setattr(piece, "lifted", lambda *args: calls.append(args[4]) or lifted(*args))
    normals = crease_normal_map(128)
    options = EncodeOptions(kind="normal-map", progress=False)
    memo = PieceMemo()
    first = encode_piece(normals, options, threshold=0.01, memo=memo)
    near = encode_piece(normals, options, threshold=0.0105, memo=memo)
    far = encode_piece(normals, options, threshold=0.02, memo=memo)
    assert calls == [0.01, 0.02]  # chosen at the first threshold and far from it, not near it
    assert memo.lifting[0] == 0.01 and memo.trees.reused == 1 and memo.trees.searched == 2
    # The directions of the first encode, at the nearby threshold: the same as choosing them again
    # where the choice does not change, and every file decodes.
    fresh = encode_piece(normals, options, threshold=0.0105)
    assert abs(len(near.data) - len(fresh.data)) < 0.02 * len(fresh.data)
    for data in (first.data, near.data, far.data):
        assert bandelets.decode(data).shape == normals.shape


def test_a_tiled_rate_target_with_the_memos_is_met():
    normals = crease_normal_map(256)
    data = bandelets.encode(normals, bpp=1.0, kind="normal-map", tile=32)
    target = normals.shape[0] * normals.shape[1] / 8
    assert container.is_tiled(data) and 0.97 * target <= len(data) <= target
    assert bandelets.decode(data).shape == normals.shape
