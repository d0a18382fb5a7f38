"""The compiled small linear programs agree with scipy's linprog (HiGHS)."""

import numpy as np
import pytest
from scipy.optimize import linprog

from bandelets.surfaces.smalllp import INFEASIBLE, OPTIMAL, UNBOUNDED, maximize
from bandelets.surfaces.sphere import _kernel_point


def highs(c, a, b, box=None):
    return linprog(-c, A_ub=a, b_ub=b, bounds=[box] * len(c), method="highs")


def test_random_programs_agree_with_highs():
    rng = np.random.default_rng(1)
    seen = set()
    for trial in range(400):
        n, m = rng.integers(1, 5), rng.integers(1, 20)
        a, c = rng.normal(size=(m, n)), rng.normal(size=n)
        b = rng.normal(size=m) + rng.uniform(-1, 2)
        if trial % 4 == 0:
            b = np.abs(b)  # x = 0 feasible
        status, x, value = maximize(c, a, b)
        seen.add(status)
        reference = highs(c, a, b, (None, None))
        if status == OPTIMAL:
            assert reference.status == 0
            assert value == pytest.approx(-reference.fun, abs=1e-7)
            assert np.max(a @ x - b) < 1e-7 and value == pytest.approx(c @ x)
        elif status == UNBOUNDED:
            # HiGHS may call such a program infeasible (unbounded or infeasible, undecided):
            # feasible, and its optimum in a box grows with the box.
            assert reference.status in (2, 3)
            small, large = highs(c, a, b, (-1e2, 1e2)), highs(c, a, b, (-1e4, 1e4))
            assert small.status == large.status == 0 and -large.fun > 10 * max(-small.fun, 1)
        else:
            assert status == INFEASIBLE and reference.status == 2
            # and the least uniform relaxation that makes it feasible is positive
            slack = linprog(
                np.r_[np.zeros(n), 1.0],
                A_ub=np.c_[a, -np.ones(m)],
                b_ub=b,
                bounds=[(None, None)] * n + [(0, None)],
                method="highs",
            )
            assert slack.fun > 1e-9
    assert seen == {OPTIMAL, INFEASIBLE, UNBOUNDED}


def test_constructed_cases():
    # x <= -1 and -x <= -1 (x >= 1): infeasible; max x with x >= 0 only: unbounded.
    assert maximize(np.array([1.0]), np.array([[1.0], [-1.0]]), np.array([-1.0, -1.0]))[0] == INFEASIBLE
    assert maximize(np.array([1.0]), np.array([[-1.0]]), np.array([0.0]))[0] == UNBOUNDED
    # A degenerate vertex: several constraints through the optimum (1, 1).
    a = np.array([[1.0, 0], [0, 1], [1, 1], [2, 1], [1, 2]])
    status, x, value = maximize(np.array([1.0, 1.0]), a, np.array([1.0, 1, 2, 3, 3]))
    assert status == OPTIMAL and value == pytest.approx(2.0) and np.allclose(x, 1.0)


def test_kernel_point_agrees_with_highs():
    # Rings of 3 to 12 triangles around a point of the sphere, their corners jittered so that
    # some kernels are empty (depth <= 0).
    rng = np.random.default_rng(2)
    empty = 0
    for _ in range(200):
        r = rng.integers(3, 13)
        angles = np.sort(rng.uniform(0, 2 * np.pi, r))
        radius = rng.uniform(0.01, 0.5)
        ring = np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.ones(r)])
        ring += rng.normal(scale=0.3 * radius, size=ring.shape) * (rng.random() < 0.5)
        points = ring / np.linalg.norm(ring, axis=1, keepdims=True)
        ring_a, ring_b = np.arange(r), np.roll(np.arange(r), -1)
        centre = points.sum(axis=0) / np.linalg.norm(points.sum(axis=0))
        point, depth = _kernel_point(points, ring_a, ring_b, centre)
        normals = np.cross(points[ring_a], points[ring_b])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        e1 = np.cross(centre, [1.0, 0, 0] if abs(centre[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(centre, e1)
        reference = linprog(
            [0.0, 0.0, -1.0],
            A_ub=np.column_stack([-(normals @ e1), -(normals @ e2), np.ones(r)]),
            b_ub=normals @ centre,
            bounds=[(-1, 1), (-1, 1), (None, 1)],
            method="highs",
        )
        assert reference.status == 0 and depth == pytest.approx(reference.x[2], abs=1e-8)
        assert np.linalg.norm(point) == pytest.approx(1.0)
        # The chart point's margin to each plane, scaled back, is at least the depth.
        chart = point / (point @ centre)
        assert np.min(chart @ normals.T) >= depth - 1e-8
        empty += depth <= 0
    assert 10 < empty < 190  # both kinds of ring were tried
