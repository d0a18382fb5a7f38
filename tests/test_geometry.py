"""Directions and reorderings of a square, and the zig-zag order (bandelets.transform.geometry)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.transform.geometry import critical_angles, directions, zigzag


@pytest.mark.parametrize("width", [4, 8])
def test_one_reordering_per_interval_between_critical_angles(width):
    angles, orders = directions(width)
    crit = critical_angles(width)
    assert crit[0] == 0.0
    assert np.all(np.diff(crit) > 0)
    assert len(orders) == len(angles) == len(crit)
    assert len(orders) < 2 * width * width


@pytest.mark.parametrize("width", [4, 8])
def test_orders_are_distinct_permutations(width):
    angles, orders = directions(width)
    assert orders.shape == (len(angles), width * width)
    for order in orders:
        assert np.array_equal(np.sort(order), np.arange(width * width))
    assert len({order.tobytes() for order in orders}) == len(orders)
    assert np.all((angles > 0) & (angles < np.pi))
    assert np.all(np.diff(angles) > 0)


@pytest.mark.parametrize("width", [4, 8])
def test_order_follows_the_direction(width):
    """Points on a line of direction d (x = column, y = row) are consecutive in order d:
    sorting by the projection on the orthogonal axis is non-decreasing."""
    angles, orders = directions(width)
    rows, cols = np.divmod(np.arange(width * width), width)
    for theta, order in zip(angles, orders, strict=True):
        t = -np.sin(theta) * cols + np.cos(theta) * rows
        assert np.all(np.diff(t[order]) >= -1e-12)


@pytest.mark.parametrize("width", [4, 8])
def test_directions_are_cached_and_read_only(width):
    first = directions(width)
    second = directions(width)
    assert first is second
    assert first[1] is second[1]
    with pytest.raises(ValueError):
        first[1][0, 0] = 1


@pytest.mark.parametrize("width", [2, 4, 8, 16])
def test_zigzag_is_a_permutation_starting_upper_left(width):
    z = zigzag(width)
    assert np.array_equal(np.sort(z), np.arange(width * width))
    assert list(z[:3]) == [0, 1, width]
    assert z[-1] == width * width - 1
    # Consecutive positions are neighbours (8-connected) along the anti-diagonals.
    r, c = np.divmod(z, width)
    assert np.all(np.maximum(np.abs(np.diff(r)), np.abs(np.diff(c))) == 1)
    assert np.all(np.diff(r + c) >= 0)


def test_zigzag_is_jpeg_order_for_4():
    jpeg = [0, 1, 4, 8, 5, 2, 3, 6, 9, 12, 13, 10, 7, 11, 14, 15]
    assert list(zigzag(4)) == jpeg
