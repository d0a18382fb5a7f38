"""A rate-control loop's geometry searched once (bandelets.search.treememo)."""

from __future__ import annotations

import numpy as np

import bandelets
from bandelets.samples import crease_normal_map
from bandelets.search.basis import best_trees
from bandelets.search.treememo import REUSE_WITHIN, TreeMemo
from bandelets.transform.bandelets import wavelet_coefficients


def _coefficients():
    x = crease_normal_map(64)
    return wavelet_coefficients(x[..., :2], "cdf97", 3, "symmetric")


def _same(a, b) -> bool:
    pairs = zip(a, b, strict=True)
    return all(np.array_equal(u, v) for p, q in pairs for u, v in zip(p.leaves(), q.leaves(), strict=True))


def test_near_threshold_reuses_far_one_searches():
    coefficients = _coefficients()
    memo = TreeMemo()
    first = memo.search(coefficients, 3, 0.02, "bandelet", "alpert2")
    assert _same(first, best_trees(coefficients, 3, 0.02, "bandelet", "alpert2"))
    near = memo.search(coefficients, 3, 0.02 * np.exp(0.9 * REUSE_WITHIN), "bandelet", "alpert2")
    assert _same(near, first) and (memo.searched, memo.reused) == (1, 1)
    far_t = 0.02 * np.exp(1.5 * REUSE_WITHIN)
    far = memo.search(coefficients, 3, far_t, "bandelet", "alpert2")
    assert _same(far, best_trees(coefficients, 3, far_t, "bandelet", "alpert2"))
    assert (memo.searched, memo.reused) == (2, 1)
    memo.search(coefficients, 3, 0.02, "wavelet", "alpert2")  # a probe: no geometry, not counted
    assert (memo.searched, memo.reused) == (2, 1)


def test_reuses_the_nearest_search_not_only_the_first():
    coefficients = _coefficients()
    memo = TreeMemo()
    memo.search(coefficients, 3, 0.02, "bandelet", "alpert2")
    second_t = 0.02 * np.exp(-1.5 * REUSE_WITHIN)  # the first file missed by more than the window
    second = memo.search(coefficients, 3, second_t, "bandelet", "alpert2")
    # Beyond the window of the first search, within that of the second: the second's trees.
    third = memo.search(coefficients, 3, second_t * np.exp(-0.5 * REUSE_WITHIN), "bandelet", "alpert2")
    assert _same(third, second) and (memo.searched, memo.reused) == (2, 1)


def test_before_hook_sees_every_subband_when_reused():
    coefficients = _coefficients()
    memo = TreeMemo()
    memo.search(coefficients, 3, 0.02, "bandelet", "alpert2")
    seen = []
    memo.search(coefficients, 3, 0.021, "bandelet", "alpert2", lambda index, trees: seen.append(index))
    assert seen == list(range(9)) and memo.reused == 1


def test_rate_target_still_met():
    x = crease_normal_map(128)
    data = bandelets.encode(x, bpp=0.7, kind="normal-map")
    target = int(0.7 * 128 * 128 / 8)
    assert 0.97 * target <= len(data) <= target
    assert bandelets.decode(data).shape == x.shape
