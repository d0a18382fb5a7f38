"""The normalised 2D wavelet transform (bandelets.transform.wavelets)."""

from __future__ import annotations

import numpy as np
import pytest
import pywt
import reference

from bandelets.format.fields import padded_shape
from bandelets.transform.wavelets import max_levels, subband_slices, wavedec, waverec

# Non-square; the coarsest subband keeps >= 8 samples a side (as the codec does), so that
# PyWavelets does not warn about boundary effects with db4.
SHAPES_LEVELS = [((64, 96), 3), ((256, 128), 4), ((32, 48), 2), ((32, 16), 1)]


@pytest.mark.parametrize("wavelet", ["cdf97", "db4", "haar", "rbio1.3"])
@pytest.mark.parametrize(("shape", "levels"), SHAPES_LEVELS)
def test_perfect_reconstruction(wavelet, shape, levels, rng):
    x = rng.standard_normal(shape)
    c = wavedec(x, wavelet, levels)
    assert c.shape == x.shape
    assert c.dtype == np.float64
    np.testing.assert_allclose(waverec(c, wavelet, levels), x, rtol=0, atol=1e-9)


@pytest.mark.parametrize("wavelet", ["db4", "haar"])
@pytest.mark.parametrize(("shape", "levels"), SHAPES_LEVELS)
def test_orthogonal_wavelets_preserve_energy(wavelet, shape, levels, rng):
    x = rng.standard_normal(shape)
    c = wavedec(x, wavelet, levels)
    assert np.sum(c**2) == pytest.approx(np.sum(x**2), rel=1e-10)


def _subbands(shape, levels):
    h, w = shape[0] >> levels, shape[1] >> levels
    yield "A", (slice(0, h), slice(0, w))
    for level, orientation, where in subband_slices(shape, levels):
        yield f"{'HVD'[orientation]}{level}", where


@pytest.mark.parametrize("levels", [1, 3])
def test_cdf97_synthesis_functions_have_unit_norm(levels):
    """Unit norm, except the finest level's: 1 / FINEST_WEIGHT (its coefficients weighted more)."""
    from bandelets.transform.wavelets import FINEST_WEIGHT

    shape = (128, 160)
    for name, (rows, cols) in _subbands(shape, levels):
        expected = 1.0 / FINEST_WEIGHT if name.endswith("1") and name != "A" else 1.0
        # Two positions well inside each subband: the centre and a point off the centre.
        for dr, dc in [(0, 0), (1, -2)]:
            c = np.zeros(shape)
            r0 = (rows.start + rows.stop) // 2 + dr
            c0 = (cols.start + cols.stop) // 2 + dc
            c[r0, c0] = 1.0
            norm = np.linalg.norm(waverec(c, "cdf97", levels))
            assert norm == pytest.approx(expected, abs=1e-6), (name, dr, dc)


def test_cdf97_is_not_orthogonal_but_normalised():
    """Sanity check of the previous test: the raw 9/7 synthesis functions are not unit-norm,
    so the normalisation is doing something (a unit impulse in the raw transform of a
    detail subband would not give norm 1)."""
    from bandelets.transform.wavelets import subband_norms

    norms = np.array(subband_norms("cdf97", 2))
    assert np.all(np.abs(norms - 1.0) > 1e-3)
    assert np.allclose(subband_norms("db4", 2), 1.0, atol=1e-9)


@pytest.mark.parametrize("wavelet", ["cdf97", "db4", "haar", "rbio1.3"])
def test_constant_image_has_no_details(wavelet):
    shape, levels = (64, 96), 3
    c = wavedec(np.full(shape, 3.25), wavelet, levels)
    h, w = shape[0] >> levels, shape[1] >> levels
    details = c.copy()
    details[:h, :w] = 0.0
    assert np.max(np.abs(details)) < 1e-9
    # ... and the approximation carries the whole image.
    assert np.all(np.abs(c[:h, :w]) > 1.0)


def test_unknown_wavelet_is_a_value_error():
    with pytest.raises(ValueError, match="unknown wavelet"):
        wavedec(np.zeros((8, 8)), "bior9.9", 1)


def test_subband_layout_covers_details_once():
    shape, levels = (32, 48), 3
    seen = np.zeros(shape, int)
    h, w = shape[0] >> levels, shape[1] >> levels
    seen[:h, :w] += 1
    order = []
    for level, orientation, where in subband_slices(shape, levels):
        seen[where] += 1
        order.append((level, orientation))
    assert np.all(seen == 1)
    # Coarsest level first, H, V, D within a level.
    assert order == [(lv, o) for lv in (3, 2, 1) for o in (0, 1, 2)]


def test_padded_shape_and_max_levels():
    assert padded_shape((37, 53), 2) == (40, 56)
    assert padded_shape((64, 64), 3) == (64, 64)
    assert max_levels((8, 8)) == 1
    assert max_levels((16, 16)) == 1
    assert max_levels((32, 200)) == 2
    assert max_levels((4096, 4096)) == 6


@pytest.mark.parametrize(("side", "levels"), [(4, 1), (16, 2), (32, 5), (64, 4), (96, 5)])
def test_spherical_extension_is_perfectly_invertible(side, levels, rng):
    x = rng.standard_normal((side, side))
    c = wavedec(x, "cdf97", levels, "spherical")
    np.testing.assert_allclose(waverec(c, "cdf97", levels, "spherical"), x, rtol=0, atol=1e-10)


def _smooth_on_the_sphere(side: int) -> np.ndarray:
    from bandelets.surfaces import octahedral

    p = octahedral.square_to_sphere(octahedral.grid(side))
    return np.exp(0.8 * p[..., 0] - 0.5 * p[..., 1] + 0.3 * p[..., 2]) + np.sin(2 * p[..., 1] + p[..., 2])


def _border_energy(c: np.ndarray, levels: int, level: int) -> float:
    """Energy of the details of ``level`` on the first and last two rows and columns of each subband."""
    total = 0.0
    for _, _, where in (s for s in subband_slices(c.shape, levels) if s[0] == level):
        band = c[where]
        inside = np.zeros(band.shape, bool)
        inside[2:-2, 2:-2] = True
        total += float(np.sum(band[~inside] ** 2))
    return total


def test_spherical_extension_shrinks_the_details_at_the_border():
    # A smooth function of the sphere point is continuous across the glued edges of the
    # octahedral image; the symmetric extension folds it the wrong way there. The map itself
    # has a kink across the edges, which no extension removes: the coarser levels, whose
    # extension interpolates over the edge, gain less than the finest one.
    f = _smooth_on_the_sphere(128)
    symmetric = wavedec(f, "cdf97", 3, "symmetric")
    spherical = wavedec(f, "cdf97", 3, "spherical")
    for level, most in ((1, 0.25), (2, 0.8), (3, 0.8)):
        assert _border_energy(spherical, 3, level) < most * _border_energy(symmetric, 3, level)
    # Away from the border the finest details do not depend on the extension.
    finest = subband_slices(f.shape, 3)[-1][2]
    np.testing.assert_allclose(spherical[finest][8:-8, 8:-8], symmetric[finest][8:-8, 8:-8], atol=1e-12)


@pytest.mark.parametrize(
    ("shape", "wavelet", "extension", "words"),
    [
        ((16, 32), "cdf97", "spherical", "square"),
        ((24, 24), "cdf97", "spherical", "multiple of 16"),
        ((16, 16), "haar", "spherical", "cdf97"),
        ((16, 16), "cdf97", "periodic", "unknown extension"),
    ],
)
def test_extension_misuse_is_refused(shape, wavelet, extension, words):
    with pytest.raises(ValueError, match=words):
        wavedec(np.zeros(shape), wavelet, 4 if shape == (24, 24) else 1, extension)


@pytest.mark.parametrize(
    ("shape", "levels", "extension"),
    [*((shape, levels, "symmetric") for shape, levels in SHAPES_LEVELS), ((2, 2), 1, "symmetric")]
    + [((side, side), levels, "spherical") for side, levels in [(4, 1), (16, 2), (32, 5), (96, 5)]],
)
def test_compiled_cdf97_lifting_is_the_numpy_one_to_the_last_bit(shape, levels, extension, rng):
    x = rng.standard_normal(shape)
    c = wavedec(x, "cdf97", levels, extension)
    assert np.array_equal(c, reference.wavedec(x, levels, extension))
    assert np.array_equal(waverec(c, "cdf97", levels, extension), reference.waverec(c, levels, extension))
    # In place, as the restoration transforms.
    y = x.copy()
    assert wavedec(y, "cdf97", levels, extension, out=y) is y
    assert np.array_equal(y, c)
    assert np.array_equal(
        waverec(y, "cdf97", levels, extension, out=y), reference.waverec(c, levels, extension)
    )


@pytest.mark.parametrize(("shape", "levels"), SHAPES_LEVELS)
def test_lifted_haar_is_pywavelets_periodic_haar(shape, levels, rng):
    x = rng.standard_normal(shape)
    coeffs = pywt.wavedec2(x, "haar", mode="periodization", level=levels)
    expected = np.empty(shape)
    h, w = shape[0] >> levels, shape[1] >> levels
    expected[:h, :w] = coeffs[0]
    for (_, _, where), band in zip(
        subband_slices(shape, levels), (b for t in coeffs[1:] for b in t), strict=True
    ):
        expected[where] = band
    # To the last bit: files coded through PyWavelets decode to the same numbers.
    assert np.array_equal(wavedec(x, "haar", levels), expected)
    assert np.array_equal(
        waverec(expected, "haar", levels), pywt.waverec2(coeffs, "haar", mode="periodization")
    )
