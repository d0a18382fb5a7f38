"""The 1D transforms along the directions and the bandeletization of a subband."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.format.fields import TRANSFORMS_1D
from bandelets.search.basis import best_quadtree
from bandelets.transform.bandeletize import bandeletize, debandeletize, transform_rows
from bandelets.transform.geometry import directions, zigzag


@pytest.mark.parametrize("kind", TRANSFORMS_1D)
@pytest.mark.parametrize("n", [4, 16, 64])
def test_transform_rows_is_orthonormal(kind, n, rng):
    x = rng.standard_normal((7, n))
    y = transform_rows(x, kind)
    assert y.shape == x.shape
    np.testing.assert_allclose(np.sum(y**2, axis=1), np.sum(x**2, axis=1), rtol=1e-12)
    np.testing.assert_allclose(transform_rows(y, kind, inverse=True), x, rtol=0, atol=1e-12)
    # The matrix of the transform is orthogonal.
    m = transform_rows(np.eye(n), kind)
    np.testing.assert_allclose(m @ m.T, np.eye(n), atol=1e-12)
    # The input is not modified.
    assert not np.shares_memory(y, x)


@pytest.mark.parametrize("n", [16, 64])
def test_alpert2_annihilates_a_ramp_except_two_coefficients(n):
    ramp = 0.7 * np.arange(n) - 3.0
    y = transform_rows(ramp[None, :], "alpert2")[0]
    assert np.max(np.abs(y[2:])) < 1e-10 * np.linalg.norm(ramp)
    assert np.linalg.norm(y[:2]) == pytest.approx(np.linalg.norm(ramp), rel=1e-12)
    # Haar does not: the ramp leaves details at every scale.
    haar = transform_rows(ramp[None, :], "haar")[0]
    assert np.sum(np.abs(haar[1:]) > 1e-6) > n // 2


def test_haar_keeps_a_constant_in_its_first_coefficient():
    y = transform_rows(np.full((1, 16), 2.0), "haar")[0]
    # (The sign of the scaling function is a convention of the QR factorisation.)
    assert abs(y[0]) == pytest.approx(8.0)
    assert np.max(np.abs(y[1:])) < 1e-12


def _hand_made_tree(rng, covered=(32, 32), root=16, null_fraction=0.3):
    """A quadtree of random shape (random costs) with random directions, NULL included."""
    levels = root.bit_length() - 2  # widths 4, 8, ..., root
    costs, dirs = [], []
    for level in range(levels):
        width = 4 << level
        cells = (covered[0] // width, covered[1] // width)
        costs.append(rng.uniform(0, 4.0 ** (level + 1), cells))
        d = rng.integers(0, len(directions(width)[0]), cells)
        d[rng.random(cells) < null_fraction] = -1
        dirs.append(d)
    return best_quadtree(costs, dirs, split_cost=1.0)


@pytest.mark.parametrize("kind", TRANSFORMS_1D)
def test_bandeletize_round_trip(kind, rng):
    tree = _hand_made_tree(rng)
    _, _, widths, dirs = tree.leaves()
    # The random tree mixes leaf sizes and NULL and non-NULL leaves.
    assert len(np.unique(widths)) >= 2
    assert np.any(dirs < 0) and np.any(dirs >= 0)
    # The subband is larger than the covered region: the rest stays wavelet.
    subband = rng.standard_normal((36, 40))
    b = bandeletize(subband, tree, kind)
    assert b.shape == subband.shape
    assert not np.allclose(b, subband)
    assert np.sum(b**2) == pytest.approx(np.sum(subband**2), rel=1e-12)
    np.testing.assert_allclose(debandeletize(b, tree, kind), subband, rtol=0, atol=1e-12)
    # Outside the covered region and in NULL squares nothing changes.
    np.testing.assert_array_equal(b[32:, :], subband[32:, :])
    np.testing.assert_array_equal(b[:, 32:], subband[:, 32:])
    for r, c, w, d in zip(*tree.leaves(), strict=True):
        if d < 0:
            np.testing.assert_array_equal(b[r : r + w, c : c + w], subband[r : r + w, c : c + w])


@pytest.mark.parametrize("kind", TRANSFORMS_1D)
def test_bandeletize_square_matches_definition(kind, rng):
    """One square: read in the order of its direction, 1D transform, store in zig-zag."""
    tree = _hand_made_tree(rng)
    subband = rng.standard_normal((32, 32))
    b = bandeletize(subband, tree, kind)
    checked = 0
    for r, c, w, d in zip(*tree.leaves(), strict=True):
        if d < 0:
            continue
        square = subband[r : r + w, c : c + w].ravel()
        coeffs = transform_rows(square[directions(int(w))[1][d]][None, :], kind)[0]
        stored = b[r : r + w, c : c + w].ravel()
        np.testing.assert_allclose(stored[zigzag(int(w))], coeffs, atol=1e-12)
        checked += 1
    assert checked > 0


def test_constant_square_keeps_one_coefficient_top_left(rng):
    tree = _hand_made_tree(rng, null_fraction=0.0)
    subband = np.full((32, 32), 1.5)
    for kind in TRANSFORMS_1D:
        b = bandeletize(subband, tree, kind)
        for r, c, w, _ in zip(*tree.leaves(), strict=True):
            square = b[r : r + w, c : c + w]
            assert abs(square[0, 0]) == pytest.approx(1.5 * w)
            rest = square.ravel()[1:]
            assert np.max(np.abs(rest)) < 1e-10
