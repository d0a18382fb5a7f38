"""The imageio v3 plugin (bandelets.io.imageio_plugin)."""

from __future__ import annotations

import numpy as np
import pytest

iio = pytest.importorskip("imageio.v3")

import bandelets  # noqa: E402
import bandelets.io.imageio_plugin  # noqa: E402, F401  (registers .bdl)
from bandelets.metrics import angular_error, psnr  # noqa: E402
from bandelets.samples import crease_normal_map  # noqa: E402


def test_imwrite_and_imread_a_bdl_file(tmp_path):
    normals = crease_normal_map(32)
    path = tmp_path / "n.bdl"
    iio.imwrite(path, normals, kind="normal-map", bpp=2)
    assert 8 * path.stat().st_size / 32**2 <= 2
    decoded = iio.imread(path)
    np.testing.assert_array_equal(decoded, bandelets.decode(path.read_bytes()))
    assert angular_error(normals, decoded).mean < 4
    assert iio.improps(path).shape == (32, 32, 3)
    assert iio.immeta(path)["kind"] == "normal-map"


def test_bytes_in_and_out_and_the_default_rate(rng):
    image = rng.random((24, 40))
    data = iio.imwrite("<bytes>", image, extension=".bdl")  # no target: 1 bpp
    assert data.startswith(b"BDL\x1a") and len(data) <= 24 * 40 / 8
    assert psnr(image, iio.imread(data)) > 10


def test_other_files_are_not_taken_for_bdl(tmp_path):
    path = tmp_path / "x.bdl"
    path.write_bytes(b"not a bdl file at all")
    with pytest.raises(OSError, match="`bandelets` can not handle"):  # imageio's words
        iio.imread(path, plugin="bandelets")
