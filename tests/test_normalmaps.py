"""Normal maps that are octahedral geometry images: found by their border, folded in the file."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets import metrics
from bandelets.format.header import pack, unpack
from bandelets.samples import bevel_normal_map, bump_normal_map, crease_normal_map
from bandelets.surfaces.octahedral import grid, square_to_sphere
from bandelets.transform.normals import octahedral


def ellipsoid_normals(size: int) -> np.ndarray:
    """The normals of a bumpy ellipsoid on the ``size`` x ``size`` octahedral grid: what
    ``make_geometry_image(mesh).normals`` gives, glued across its border, without a mesh."""
    p = square_to_sphere(grid(size))
    bumps = 1.0 + 0.3 * np.sin(4.0 * p[..., 0]) * np.cos(3.0 * p[..., 1] + 1.0)
    n = p / np.array([1.0, 0.6, 0.4]) * bumps[..., None] + np.array([0.2, -0.1, 0.3])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@pytest.fixture(scope="module")
def folded_map():
    return ellipsoid_normals(64)


def test_an_octahedral_map_is_found_and_turned_or_flipped_still_is(folded_map):
    assert octahedral(folded_map)
    # A quarter turn or a flip maps the edges onto edges, each still glued to itself reversed.
    assert octahedral(np.rot90(folded_map))
    assert octahedral(folded_map[::-1])


@pytest.mark.parametrize(
    "changed",
    [
        lambda x: np.roll(x, 16, axis=1),  # the border moved inside: the folds no longer meet
        lambda x: x[:, :-1],  # not square
        lambda x: x[:48, :48],  # a corner of it
        lambda x: np.broadcast_to(x[32:33, 32:33], x.shape),  # flat: no evidence
        lambda x: np.concatenate([x[:, :32], x[:, :32][:, ::-1] * np.array([-1.0, 1.0, 1.0])], axis=1),
    ],
)
def test_a_map_not_glued_so_is_not_taken_for_one(folded_map, changed):
    assert not octahedral(np.ascontiguousarray(changed(folded_map)))


@pytest.mark.parametrize("made", [crease_normal_map, bump_normal_map, bevel_normal_map])
def test_generated_maps_are_not_octahedral(made):
    vectors = made(64)
    if vectors.dtype == np.uint8:  # the bevel map's PNG samples
        vectors = vectors / 255.0 * 2.0 - 1.0
    assert not octahedral(metrics.unit_vectors(vectors))


def test_the_file_of_an_octahedral_map_is_folded_and_its_restoration_uses_the_folds(folded_map):
    data = bandelets.encode(folded_map, bpp=0.5, kind="normal-map")
    header, streams = unpack(data)
    assert header.folded and header.restoration > 0
    unfolded = bandelets.decode(pack(replace(header, folded=False), streams))
    decoded = bandelets.decode(data)
    assert not np.array_equal(decoded, unfolded)
    assert metrics.psnr(folded_map, decoded, "normal-map") > metrics.psnr(folded_map, unfolded, "normal-map")
    assert not unpack(bandelets.encode(crease_normal_map(64), bpp=0.5, kind="normal-map"))[0].folded
