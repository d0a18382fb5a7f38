"""The chart route's normal-layer trials: the shares at the best side and at the smaller one,
then the best restored by the decoder, the file kept the one that measured best."""

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("DracoPy")
pytest.importorskip("pymeshlab")

from bandelets.surfaces import chartcodec, normallayer  # noqa: E402


def test_layer_tried_at_the_smaller_side_and_restored(monkeypatch):
    sphere = trimesh.creation.icosphere(3)
    cut = trimesh.Trimesh(sphere.vertices, sphere.faces[sphere.triangles_center[:, 2] < 0.5])
    cut.remove_unreferenced_vertices()
    calls, results = [], []
    layered = chartcodec._Trials.layered

    def recorded(self, variant, side, share, restored=False):
        result = layered(self, variant, side, share, restored)
        calls.append((side, share, restored))
        results.append(result)
        return result

    monkeypatch.setattr(chartcodec._Trials, "layered", recorded)
    data = chartcodec.encode_charts(cut, 8 * 1200.0, fallback=False)
    sides = sorted({side for side, _, restored in calls if not restored})
    assert len(sides) == 2 and sides[0] == int(round(sides[1] * chartcodec.SIDE_FACTORS[0] / 2.0) * 2)
    assert {share for _, share, _ in calls} == set(normallayer.IMAGE_SHARES)
    restored = [k for k, call in enumerate(calls) if call[2]]
    assert restored == [len(calls) - 1]  # once, last, at the best unrestored share and side
    unrestored = [r for r, c in zip(results, calls, strict=True) if not c[2]]
    best = max(unrestored, key=lambda r: r[0])
    assert calls[-1][:2] == (best[3], calls[unrestored.index(best)][1])
    if max(r[0] for r in results) > best[0] and np.isfinite(results[-1][0]):
        assert data[5] & chartcodec.LAYER and chartcodec.describe(data)["side"] == calls[-1][0]
