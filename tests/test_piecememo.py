"""A tile's later passes reuse the directions and geometry of the last pass that chose them, where near
it (bandelets.codec.piecememo)."""

from __future__ import annotations

import pytest

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
    near = encode_piece(normals, options, threshold=0.0103, memo=memo)
    far = encode_piece(normals, options, threshold=0.0109, memo=memo)
    nearer = encode_piece(normals, options, threshold=0.011, memo=memo)
    # Chosen at the first threshold and 9 % from it, not 3 % from it nor 1 % from the last choice.
    assert calls == [0.01, 0.0109]
    assert memo.lifting[0] == 0.0109 and memo.trees.searches[-1][0] == pytest.approx(0.0109, rel=1e-6)
    # The trees searched at the first and at 9 % from it; those reused 3 % and 1 % from them.
    assert (memo.trees.searched, memo.trees.reused) == (2, 2)
    # The choices of the first encode 3 % away: a file of about the size of choosing them again,
    # and every file decodes.
    fresh = encode_piece(normals, options, threshold=0.0103)
    assert abs(len(near.data) - len(fresh.data)) < 0.02 * len(fresh.data)
    for data in (first.data, near.data, far.data, nearer.data):
        assert bandelets.decode(data).shape == normals.shape


def test_a_tiled_rate_target_with_the_memos_is_met():
    normals = crease_normal_map(256)
    data = bandelets.encode(normals, bpp=1.0, kind="normal-map", tile=32)
    target = normals.shape[0] * normals.shape[1] / 8
    assert container.is_tiled(data) and 0.97 * target <= len(data) <= target
    assert bandelets.decode(data).shape == normals.shape
