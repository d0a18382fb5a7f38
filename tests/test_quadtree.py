"""The best quadtree of a subband (bandelets.transform.quadtree)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.search.basis import best_quadtree
from bandelets.transform import quadtree
from bandelets.transform.quadtree import MIN_WIDTH, Quadtree, flat_quadtree, root_width


def _two_level_costs():
    # Every width-4 square costs 1: the four children of a width-8 square cost 4.
    fine = np.ones((4, 4))
    coarse = np.array([[3.0, 4.5], [4.75, 1.0]])
    dirs = [np.arange(16).reshape(4, 4), np.array([[7, -1], [5, 3]])]
    return [fine, coarse], dirs


def test_merge_rule_two_levels():
    costs, dirs = _two_level_costs()
    tree = best_quadtree(costs, dirs, split_cost=0.5)  # children + split = 4.5
    assert tree.root == 8
    # (0,0): 3 < 4.5 merged; (0,1): 4.5 == 4.5 tie, not merged; (1,0): 4.75 > 4.5 kept;
    # (1,1): 1 < 4.5 merged.
    np.testing.assert_array_equal(tree.leaf[1], [[True, False], [False, True]])
    rows, cols, widths, d = tree.leaves()
    leaves = {(int(r), int(c), int(w), int(k)) for r, c, w, k in zip(rows, cols, widths, d, strict=True)}
    expected = {(0, 0, 8, 7), (8, 8, 8, 3)}
    for r0, c0 in [(0, 8), (8, 0)]:
        for r in (r0, r0 + 4):
            for c in (c0, c0 + 4):
                expected.add((r, c, 4, int(dirs[0][r // 4, c // 4])))
    assert leaves == expected
    assert len(rows) == 10


def test_split_cost_changes_the_merges():
    costs, dirs = _two_level_costs()
    # No split cost: children cost 4; only squares cheaper than 4 merge.
    tree = best_quadtree(costs, dirs, split_cost=0.0)
    np.testing.assert_array_equal(tree.leaf[1], [[True, False], [False, True]])
    costs[1][0, 0] = 4.0  # tie with the children, split cost 0: kept split
    tree = best_quadtree(costs, dirs, split_cost=0.0)
    np.testing.assert_array_equal(tree.leaf[1], [[False, False], [False, True]])
    # A large split cost merges everything.
    tree = best_quadtree(costs, dirs, split_cost=1.0)
    np.testing.assert_array_equal(tree.leaf[1], [[True, True], [True, True]])
    assert len(tree.leaves()[0]) == 4
    # Split cost 0.75: children + split = 4.75, a tie with (1, 0), which stays split.
    tree = best_quadtree(costs, dirs, split_cost=0.75)
    np.testing.assert_array_equal(tree.leaf[1], [[True, True], [False, True]])
    assert len(tree.leaves()[0]) == 7


def _reference_leaves(costs, split_cost):
    """Paper's rule, recursively: returns {(row, col, width)} and the best cost."""

    def best(level, r, c):
        width = MIN_WIDTH << level
        if level == 0:
            return costs[0][r, c], {(r * width, c * width, width)}
        total, leaves = split_cost, set()
        for dr in (0, 1):
            for dc in (0, 1):
                cost, sub = best(level - 1, 2 * r + dr, 2 * c + dc)
                total += cost
                leaves |= sub
        if costs[level][r, c] < total:
            return costs[level][r, c], {(r * width, c * width, width)}
        return total, leaves

    top = len(costs) - 1
    out = set()
    for r in range(costs[top].shape[0]):
        for c in range(costs[top].shape[1]):
            out |= best(top, r, c)[1]
    return out


def _random_tree(rng, roots=(2, 3), levels=3, split_cost=None):
    costs, dirs = [], []
    for level in range(levels):
        cells = (roots[0] << (levels - 1 - level), roots[1] << (levels - 1 - level))
        costs.append(rng.uniform(0, 4.0**level * 4, cells))
        dirs.append(rng.integers(-1, 10, cells))
    split_cost = rng.uniform(0, 2) if split_cost is None else split_cost
    return costs, dirs, split_cost


@pytest.mark.parametrize("seed", range(5))
def test_best_quadtree_matches_recursive_rule(seed):
    rng = np.random.default_rng(seed)
    costs, dirs, split_cost = _random_tree(rng)
    tree = best_quadtree(costs, dirs, split_cost)
    rows, cols, widths, d = tree.leaves()
    got = {(int(r), int(c), int(w)) for r, c, w in zip(rows, cols, widths, strict=True)}
    assert got == _reference_leaves(costs, split_cost)
    # Each leaf carries the direction given for its square.
    for r, c, w, k in zip(rows, cols, widths, d, strict=True):
        level = int(w).bit_length() - MIN_WIDTH.bit_length()
        assert k == dirs[level][r // w, c // w]


@pytest.mark.parametrize("seed", range(5))
def test_leaves_tile_the_region_in_causal_order(seed):
    rng = np.random.default_rng(100 + seed)
    costs, dirs, split_cost = _random_tree(rng)
    tree = best_quadtree(costs, dirs, split_cost)
    height, width = tree.covered
    assert (height, width) == (2 * 16, 3 * 16)
    owner = np.full((height, width), -1)
    rows, cols, widths, _ = tree.leaves()
    assert len(np.unique(widths)) >= 2
    for i, (r, c, w) in enumerate(zip(rows, cols, widths, strict=True)):
        assert r % w == 0 and c % w == 0
        assert np.all(owner[r : r + w, c : c + w] == -1), "leaves overlap"
        owner[r : r + w, c : c + w] = i
    assert np.all(owner >= 0), "leaves leave a hole"
    # Every leaf touching this one from above or from the left comes earlier.
    for i, (r, c, w) in enumerate(zip(rows, cols, widths, strict=True)):
        if r > 0:
            assert np.all(owner[r - 1, c : c + w] < i)
        if c > 0:
            assert np.all(owner[r : r + w, c - 1] < i)


def test_leaves_of_a_flat_quadtree():
    tree = flat_quadtree((40, 72), 16)
    assert tree.covered == (32, 64)
    rows, cols, widths, d = tree.leaves()
    assert np.all(widths == 16)
    assert np.all(d == -1)
    assert list(zip(rows.tolist(), cols.tolist(), strict=True)) == [
        (r, c) for r in (0, 16) for c in (0, 16, 32, 48)
    ]
    empty = flat_quadtree((8, 8), 0)
    assert empty.root == 0
    assert empty.covered == (0, 0)
    assert all(len(a) == 0 for a in empty.leaves())


def test_single_level_tree():
    costs = [np.array([[1.0, 2.0]])]
    tree = best_quadtree(costs, [np.array([[3, -1]])], split_cost=1.0)
    assert isinstance(tree, Quadtree)
    assert tree.root == 4
    rows, cols, widths, d = tree.leaves()
    assert list(cols) == [0, 4] and list(rows) == [0, 0]
    assert list(d) == [3, -1]


def _paper_root_width(side: int) -> int:
    """Largest power of two L >= 4 with L * L <= side (the paper's bound), else 0."""
    width, candidate = 0, MIN_WIDTH
    while candidate * candidate <= side:
        width, candidate = candidate, 2 * candidate
    return width


@pytest.mark.parametrize(
    ("shape", "expected"),
    [
        ((16, 16), 4),
        ((64, 64), 8),
        ((15, 15), 0),
        ((3, 3), 0),
        ((16, 1000), 4),
        ((1000, 15), 0),
        ((63, 63), 4),
    ],
)
def test_root_width(shape, expected):
    assert root_width(shape) == expected


@pytest.mark.parametrize(
    ("shape", "expected"),
    [((256, 256), 32), ((255, 255), 16), ((128, 512), 16), ((1024, 1024), 32), ((4096, 64), 8)],
)
def test_root_width_of_large_subbands(shape, expected):
    """Roots reach ``max(sqrt(side), side / 8)``, capped at MAX_WIDTH, and never fall below
    the paper's sqrt(width) bound."""
    side = min(shape)
    assert root_width(shape) == expected
    assert expected >= min(_paper_root_width(side), quadtree.MAX_WIDTH)
    assert expected <= quadtree.MAX_WIDTH
