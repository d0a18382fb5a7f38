"""Contexts of the 1D bandelet coefficients read around their square (bandelets.coding.squarecontexts)."""

from __future__ import annotations

import numpy as np
import pytest

import bandelets
from bandelets.coding import image as coding
from bandelets.coding.coefficients import N_HINTS, SQUARE_START
from bandelets.coding.order import subband_box, subband_plan
from bandelets.coding.squarecontexts import square_hints
from bandelets.format.header import unpack
from bandelets.format.levels import parts
from bandelets.format.quantizer import RECONSTRUCTION
from bandelets.samples import crease_normal_map
from bandelets.transform.bandeletize import transform_rows
from bandelets.transform.geometry import directions
from bandelets.transform.quadtree import flat_quadtree, root_width
from bandelets.transform.wavelets import subband_slices

SHAPE, LEVELS = (128, 128), 3


def _tree_with_one_direction(index: int, direction: int):
    _, _, where = subband_slices(SHAPE, LEVELS)[index]
    band = (where[0].stop - where[0].start, where[1].stop - where[1].start)
    tree = flat_quadtree(band, root_width(band))
    tree.direction[-1][1, 0] = direction  # the root square in the second row, first column
    return tree


@pytest.mark.parametrize(("level", "orientation"), [(1, 1), (1, 2), (3, 0)])
def test_hints_read_the_sibling_along_the_direction_and_the_parent_under_the_support(level, orientation, rng):
    index = next(
        i for i, (lv, o, _) in enumerate(subband_slices(SHAPE, LEVELS)) if (lv, o) == (level, orientation)
    )
    direction = 3
    tree = _tree_with_one_direction(index, direction)
    known = rng.integers(-3, 4, SHAPE[0] * SHAPE[1]) * (rng.random(SHAPE[0] * SHAPE[1]) < 0.4)
    hints = square_hints(known, SHAPE, LEVELS, index, tree, "alpert2")
    squares, _ = subband_plan(SHAPE, LEVELS, index, tree, "alpert2")
    side = tree.root
    n = side * side
    assert hints.shape == squares.order.shape == (n,)
    assert hints[0] & SQUARE_START and not np.any(hints[1:] & SQUARE_START)
    hint = hints & (SQUARE_START - 1)
    assert np.all(hint < N_HINTS)

    rows, cols = np.divmod(directions(side)[1][direction].astype(np.int64), side)
    rows = rows + side
    grid = known.reshape(SHAPE)
    if orientation:
        y0, x0 = subband_box(SHAPE, level, orientation - 1)[:2]
        q = grid[y0 + rows, x0 + cols]
        x = np.where(q == 0, 0.0, np.sign(q) * (np.abs(q) + RECONSTRUCTION))
        predicted = np.abs(transform_rows(x[None, :], "alpert2")[0])
        expected_bucket = np.searchsorted([1.0, 2.0, 4.0, 8.0], predicted, side="right")
    else:
        expected_bucket = np.full(n, 5)
    if level < LEVELS:
        y0, x0 = subband_box(SHAPE, level + 1, orientation)[:2]
        under = np.abs(grid[y0 + rows // 2, x0 + cols // 2])
        # Alpert (k = 2): 2 scaling functions on all n reordered samples, then at each scale s
        # 2 wavelets per group of n / 2**s samples.
        expected_parent = np.empty(n, np.int64)
        for j in range(n):
            if j < 2:
                group = under
            else:
                s = int(np.log2(j // 2))
                size = n >> s
                first = (j - 2 * 2**s) // 2 * size
                group = under[first : first + size]
            expected_parent[j] = min(group.max(), 2)
    else:
        expected_parent = np.full(n, 3)
    np.testing.assert_array_equal(hint, expected_bucket * 4 + expected_parent)


def test_hints_pay_on_the_crease_map(monkeypatch):
    """What the hints read around a square lowers the cost of its coefficients: the same file's
    bins coded with every hint set to 0 cost more."""
    data = bandelets.encode(crease_normal_map(128), threshold=0.03, kind="normal-map")
    header, streams = unpack(data)
    trees, bins, spent = coding.code_image(coding.new_coders(parts(streams, header.segments)), header)
    assert any(np.any(t.leaves()[3] >= 0) for t in trees), "no bandelet square to test"

    def without_hints(*args):
        return square_hints(*args) & SQUARE_START

    monkeypatch.setattr(coding, "square_hints", without_hints)
    _, _, plain = coding.code_image(coding.new_coders(), header, trees, bins)
    assert sum(s.sum() for s in spent) < sum(p.sum() for p in plain)
