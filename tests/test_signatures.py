"""Kernels compiled for given signatures only (runtime/signatures.py), and the lifting's two layouts."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.runtime.signatures import kernel
from bandelets.transform import directional, lifting, wavelets


def _double(x):
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            x[i, j] *= 2.0


def test_a_kernel_compiles_its_signature_once_for_every_layout():
    double = kernel("void(f8[:, :])")(_double)
    assert double.dispatcher.signatures == []  # nothing before the first call
    base = np.arange(24.0).reshape(4, 6)
    for view in (base, base.T, base[::2, 1:]):  # row-major, column-major, strided
        expected = 2 * view
        double(view)
        assert np.array_equal(view, expected)
    assert len(double.dispatcher.signatures) == 1


def test_a_kernel_refuses_what_its_signature_cannot_take():
    double = kernel("void(f8[:, :])")(_double)
    with pytest.raises(TypeError):
        double(np.zeros(3))  # one dimension: no conversion, and no compilation of another kernel
    assert len(double.dispatcher.signatures) == 1


def test_the_lifting_passes_keep_two_layouts():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((64, 64))
    wavelets.waverec(wavelets.wavedec(x, "cdf97", 3), "cdf97", 3)  # row-major, transposes, corners
    fields = [np.zeros(shape, np.int64) for shape in directional.field_shapes(x.shape, 2)]
    directional.transform(directional.transform(x.copy(), 3, 2, fields), 3, 2, fields, inverse=True)
    for name in ("_split", "_merge", "_normalise", "_lift", "_lift_along", "_rescale"):
        layouts = {sig[0].layout for sig in getattr(lifting, name).dispatcher.signatures}
        assert layouts == {"C", "A"}, name
