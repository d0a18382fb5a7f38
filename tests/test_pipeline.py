"""The encoder's two coding passes in step on two cores (bandelets.codec.pipeline): the same files; the
rows of elementwise functions in two threads (bandelets.runtime.threads.by_rows): the same numbers."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets.codec import at_threshold, pipeline
from bandelets.codec.levels import decode_level
from bandelets.coding import image
from bandelets.format.fields import Kind
from bandelets.format.header import Header, unpack
from bandelets.runtime import threads
from bandelets.samples import bevel_normal_map, crease_normal_map
from bandelets.transform import normals


def _encodes(monkeypatch, stepped: bool, image, **target) -> tuple[bytes, int]:
    """The file of ``image`` with the two passes in step (``stepped``) or one after the other, and how
    many files were coded in step."""
    calls = []

    def counted(*args):
        calls.append(1)
        return pipeline.code_in_step(*args)

    monkeypatch.setattr(pipeline, "IN_STEP_FROM", 256 * 256)  # small images, quick tests
    monkeypatch.setattr(at_threshold, "in_step", lambda header: stepped and pipeline.in_step(header))
    monkeypatch.setattr(at_threshold, "code_in_step", counted)
    return bandelets.encode(image, kind="normal-map", **target), len(calls)


@pytest.mark.skipif(threads.CORES < 2, reason="one core: the passes run one after the other")
@pytest.mark.parametrize(
    ("image", "target"),
    [
        (crease_normal_map(256), {"threshold": 0.02}),
        (bevel_normal_map(256), {"bpp": 1.0}),
    ],
)
def test_in_step_codes_the_same_bytes(monkeypatch, image, target):
    serial, none = _encodes(monkeypatch, False, image, **target)
    stepped, used = _encodes(monkeypatch, True, image, **target)
    assert none == 0 and used >= 1
    assert stepped == serial


def test_not_in_step_below_its_size_nor_inside_a_map():
    def header(side: int) -> Header:
        return Header(
            height=side,
            width=side,
            channels=2,
            kind=Kind.NORMAL_MAP,
            transform="bandelet",
            wavelet="cdf97",
            levels=4,
            threshold=0.1,
        )

    large = header(1024)
    assert not pipeline.in_step(header(512))
    assert not pipeline.in_step(replace(large, frames=True))
    assert pipeline.in_step(large) == (threads.CORES > 1)
    assert list(threads.thread_map(lambda _: pipeline.in_step(large), range(2))) == [False, False]


def test_an_error_of_the_first_pass_reaches_the_caller(monkeypatch):
    if threads.CORES < 2:
        pytest.skip("one core: no first pass in a thread")

    def failing(coders, header, trees, quantized, **kwargs):
        if "spent" in kwargs:  # the first pass
            raise RuntimeError("first pass failed")
        return original(coders, header, trees, quantized, **kwargs)

    original = pipeline.code_image
    monkeypatch.setattr(pipeline, "IN_STEP_FROM", 256 * 256)
    monkeypatch.setattr(pipeline, "code_image", failing)
    with pytest.raises(RuntimeError, match="first pass failed"):
        bandelets.encode(crease_normal_map(256), kind="normal-map", threshold=0.02)


def test_by_rows_makes_the_same_numbers_as_one_call():
    rng = np.random.default_rng(3)
    vectors = rng.normal(size=(1024, 512, 3))
    assert vectors.size >= threads.BY_ROWS_FROM
    whole = normals.unit_vectors(vectors)
    assert np.array_equal(threads.by_rows(normals.unit_vectors, vectors), whole)
    assert np.array_equal(threads.by_rows(normals.equidistant, whole), normals.equidistant(whole))
    small = vectors[:8]
    assert np.array_equal(threads.by_rows(normals.unit_vectors, small), normals.unit_vectors(small))


@pytest.mark.parametrize(
    ("image_of", "lifting", "level"),
    [(bevel_normal_map, None, 0), (bevel_normal_map, None, 2), (crease_normal_map, True, 0)],
)
def test_quadtrees_decoded_ahead_give_the_same_image(monkeypatch, image_of, lifting, level):
    data = bandelets.encode(image_of(256), kind="normal-map", bpp=1.0, lifting=lifting)
    assert (unpack(data)[0].lifting > 0) == bool(lifting)
    monkeypatch.setattr(image, "AHEAD_FROM", 1 << 60)
    alone = decode_level(data, level) if level else bandelets.decode(data)
    monkeypatch.setattr(image, "AHEAD_FROM", 256 * 256)
    names = []

    def geometry(*args):
        names.append(threading.current_thread().name)
        return original(*args)

    original = image._geometry
    monkeypatch.setattr(image, "_geometry", geometry)
    ahead = decode_level(data, level) if level else bandelets.decode(data)
    assert np.array_equal(ahead, alone)
    assert any(n.startswith("bandelets") for n in names) == (threads.CORES > 1)
