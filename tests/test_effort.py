"""The encoder's effort (issue 36): the same format at every effort; from FULL_TRIALS_FROM a rate-control
loop per alternative tried, from TRIALS_FROM one loop on the alternative of least cost at one threshold,
below it one loop on what the estimates choose; below GEOMETRY_FROM no bandelet geometry but on the maps the
hard-surface guess claims; below LOOP_FILTER_FROM no loop filter either."""

from __future__ import annotations

from pathlib import Path

import imagecodecs
import pytest

import bandelets
from bandelets.apps.cli import main
from bandelets.codec import hardsurface, piece
from bandelets.codec.options import FULL_TRIALS_FROM, GEOMETRY_FROM, LOOP_FILTER_FROM, TRIALS_FROM
from bandelets.format.header import unpack
from bandelets.samples import bevel_normal_map
from bandelets.search import treememo

REAL = (
    Path(__file__).resolve().parents[2] / "shared" / "data" / "normal-maps" / "godot_scifi_vent_decal_512.png"
)


@pytest.fixture(scope="module")
def vent():
    if not REAL.exists():
        pytest.skip(f"shared real map absent: {REAL}")
    return imagecodecs.imread(REAL)[..., :3]


def _loops(monkeypatch, x, effort):
    """The rate-control loops an encode of ``x`` at 1 bpp makes, the alternatives it weighed at one
    threshold, and its file."""
    loops, weighed = [], []
    search, cheapest = piece._PieceEncoder._search_size, piece._PieceEncoder._cheapest

    def counted(self, candidate, *args):
        loops.append(candidate)
        return search(self, candidate, *args)

    def compared(self, candidate, trials, *args):
        weighed.append(1 + len(trials))
        return cheapest(self, candidate, trials, *args)

    # the alternatives of the defaults: the vent decal's runs would have them guess effort 9's variant
    monkeypatch.setattr(hardsurface, "wants_haar_along_directions", lambda array: False)
    monkeypatch.setattr(piece._PieceEncoder, "_search_size", counted)
    monkeypatch.setattr(piece._PieceEncoder, "_cheapest", compared)
    return loops, weighed, bandelets.encode(x, bpp=1.0, kind="normal-map", effort=effort)


def test_each_effort_tries_the_alternatives_as_documented(monkeypatch, vent):
    loops, weighed, full = _loops(monkeypatch, vent, FULL_TRIALS_FROM)
    assert len(loops) >= 2 and not weighed  # the real map's Riesz pair is close to paying: both files
    loops, weighed, picked = _loops(monkeypatch, vent, TRIALS_FROM)
    assert len(loops) == 1 and weighed and weighed[0] >= 2  # weighed at one threshold, one loop
    loops, weighed, fast = _loops(monkeypatch, vent, TRIALS_FROM - 1)
    assert len(loops) == 1 and not weighed
    for data in (full, picked, fast):  # the same target, met alike
        assert 0.97 * 512 * 512 / 8 <= len(data) <= 512 * 512 / 8


def test_below_loop_filter_from_no_filter_is_written(vent):
    with_filter = unpack(bandelets.encode(vent, bpp=1.0, kind="normal-map"))[0]
    without = unpack(bandelets.encode(vent, bpp=1.0, kind="normal-map", effort=LOOP_FILTER_FROM - 1))[0]
    assert with_filter.loop_filter is not None
    assert without.loop_filter is None


@pytest.mark.parametrize("claimed", [False, True])
def test_below_geometry_from_only_hard_surface_maps_search_the_geometry(monkeypatch, claimed):
    monkeypatch.setattr(hardsurface, "wants_haar_along_directions", lambda array: claimed)
    searches = []
    search = treememo.best_trees  # the rate-control loop's searches of the geometry
    monkeypatch.setattr(treememo, "best_trees", lambda *args: searches.append(args[3]) or search(*args))
    x = bevel_normal_map(128)
    fast = unpack(bandelets.encode(x, bpp=1.0, kind="normal-map", effort=GEOMETRY_FROM - 1))[0]
    assert fast.transform == ("bandelet" if claimed else "wavelet")
    assert ("bandelet" in searches) == claimed
    searches.clear()
    assert (
        unpack(bandelets.encode(x, bpp=1.0, kind="normal-map", effort=GEOMETRY_FROM))[0].transform
        == "bandelet"
    )
    assert "bandelet" in searches


@pytest.mark.parametrize("effort", [0, 10, 7.5, "7"])
def test_an_effort_out_of_range_is_refused(effort):
    with pytest.raises(ValueError, match="effort must be a whole number from 1 to 9"):
        bandelets.EncodeOptions(effort=effort)


@pytest.mark.parametrize("value", ["0", "10", "nan", "7.5"])
def test_the_command_line_refuses_an_effort_out_of_range(tmp_path, capsys, value):
    status = main(["encode", str(tmp_path / "in.png"), str(tmp_path / "out.bdl"), "--effort", value])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--effort" in err[0]
    assert not (tmp_path / "out.bdl").exists()
