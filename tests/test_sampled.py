"""The lifting's choices of a large image made on a mosaic of its crops (bandelets.search.sampled)."""

from __future__ import annotations

import numpy as np

from bandelets.codec import alternatives
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.search import directions, sampled
from bandelets.transform.bandelets import padded_channels, wavelet_coefficients
from bandelets.transform.directional import SLOPES_97
from bandelets.transform.normals import equidistant, unit_vectors


def test_mosaic_holds_a_share_of_the_crops_of_every_row_and_column():
    side = 2048
    x = np.arange(side * side, dtype=np.float64).reshape(side, side)
    [m] = sampled.mosaic([x], 6, 0.125)
    assert m.shape == (side, side // 8)  # one crop of 256 per row of crops
    crops = {
        (int(m[r, c]) // side // 256, int(m[r, c]) % side // 256)
        for r in range(0, side, 256)
        for c in (0, 128)
    }
    assert (
        len(crops) == 8 and {r for r, _ in crops} == set(range(8)) and {c for _, c in crops} == set(range(8))
    )
    for r in range(8):  # each crop is the source's, whole
        top, left = r * 256, next(c for q, c in crops if q == r) * 256
        assert np.array_equal(m[top : top + 256, :256], x[top : top + 256, left : left + 256])
    [narrow] = sampled.mosaic([x[:, :512]], 6, 0.125)  # two columns of crops: every fourth row of crops
    assert narrow.shape == (512, 256)
    strip = x[:128]  # shorter than a crop: not sampled
    assert sampled.mosaic([strip], 6, 0.125)[0] is strip


def _channels(normals: np.ndarray, levels: int) -> list[np.ndarray]:
    return padded_channels(equidistant(unit_vectors(normals)), levels)


def test_a_sample_chooses_as_the_whole_image_and_lifts_the_whole_image(monkeypatch):
    monkeypatch.setattr(sampled, "CROP", 64)
    levels, t = 5, 0.02
    crease = _channels(crease_normal_map(512), levels)
    plain = [np.zeros(1)]
    coefficients, fields, lifted, _ = sampled.lifted(crease, plain, levels, 2, t, True, False)
    whole = directions.lift(crease, levels, 2, t)
    assert fields is not None and lifted == whole[2]  # the directions pay on the crease, as on the whole
    pairs = any(np.any(f >= len(SLOPES_97)) for f in fields)
    again, chosen = directions.chosen_analysis(crease, levels, lifted, t, pairs)
    assert all(np.array_equal(a, b) for a, b in zip(fields, chosen, strict=True))
    assert all(np.array_equal(a, b) for a, b in zip(coefficients, again, strict=True))
    # Smooth bumps: the directions do not pay, the plain coefficients are returned as they are.
    bumps = bump_normal_map(512)
    out = sampled.lifted(_channels(bumps, levels), plain, levels, 2, t, True, False)
    assert out[0] is plain and out[1:] == (None, 0, None)


def test_large_images_take_the_sample_path(monkeypatch):
    calls = []
    monkeypatch.setattr(sampled, "SAMPLED_ABOVE", 256 * 256)
    monkeypatch.setattr(sampled, "lifted", lambda *args: calls.append(args) or ([], None, 0, None))
    coded = equidistant(unit_vectors(crease_normal_map(256)))
    plain = wavelet_coefficients(coded, "cdf97", 4)
    alternatives.lifted(coded, plain, 4, 2, 0.02, True)
    assert not calls  # 256 x 256 is not above SAMPLED_ABOVE
    coded = equidistant(unit_vectors(crease_normal_map(512)))
    alternatives.lifted(coded, plain, 4, 2, 0.02, True)
    assert len(calls) == 1
