"""``bandelets demo``."""

from __future__ import annotations

import imagecodecs
import numpy as np

import bandelets
from bandelets.apps.cli import main
from bandelets.metrics import psnr
from bandelets.samples import crease_normal_map

RATES = ["0.5", "1", "2", "4"]


def test_demo(tmp_path, capsys):
    status = main(["demo", "--size", "64", "--rates", ",".join(RATES), "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert "error" not in err

    rows = {}
    for line in out.splitlines():
        fields = line.split()
        if fields and fields[0] in ("bandelet", "wavelet"):
            codec, target, n_bytes, bpp, db = fields[:5]
            rows[codec, target] = (int(n_bytes), float(bpp), float(db))
    assert set(rows) == {(c, r) for c in ("bandelet", "wavelet") for r in RATES}

    bd_lines = [line for line in out.splitlines() if line.startswith("BD-PSNR")]
    assert len(bd_lines) == 1
    gain = float(bd_lines[0].split()[-2])
    assert np.isfinite(gain)

    png = tmp_path / "crease-normals.png"
    pixels = imagecodecs.png_decode(png.read_bytes())
    assert pixels.dtype == np.uint16 and pixels.shape == (64, 64, 3)
    reference = crease_normal_map(64)
    np.testing.assert_allclose(pixels / 65535 * 2 - 1, reference, atol=1e-4)

    for (codec, target), (n_bytes, bpp, db) in rows.items():
        path = tmp_path / f"{codec}-{target}bpp.bdl"
        assert path.stat().st_size == n_bytes
        assert bpp == round(8 * n_bytes / (64 * 64), 4)
        rate = float(target)
        assert 0.97 * rate * 64 * 64 / 8 <= n_bytes <= rate * 64 * 64 / 8
        # The printed PSNR is that of the file written.
        decoded = bandelets.decode(path.read_bytes())
        assert abs(psnr(reference, decoded, "normal-map") - db) < 0.01
    # Quality grows with the rate, for both codecs.
    for codec in ("bandelet", "wavelet"):
        psnrs = [rows[codec, r][2] for r in RATES]
        assert psnrs == sorted(psnrs)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["crease-normals.png"] + [f"{c}-{r}bpp.bdl" for c in ("bandelet", "wavelet") for r in RATES]
    )
