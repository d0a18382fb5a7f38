"""One BLAS thread while the codec runs (issue 36), and the loop filter's compiled products."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import bandelets
from bandelets.codec import decoder
from bandelets.restore import loopfilter
from bandelets.runtime import blas as blasthreads
from bandelets.samples import crease_normal_map
from bandelets.transform import normals

pytest.importorskip("threadpoolctl")


def test_limit_nests_and_restores():
    before = blasthreads.blas_threads()
    with blasthreads.one_blas_thread():
        with blasthreads.one_blas_thread():
            assert all(n == 1 for n in blasthreads.blas_threads())
        assert all(n == 1 for n in blasthreads.blas_threads())  # the outer context still holds
    assert blasthreads.blas_threads() == before


def test_limit_held_until_the_last_thread_leaves():
    before = blasthreads.blas_threads()
    entered, release = threading.Event(), threading.Event()

    def other():
        with blasthreads.one_blas_thread():
            entered.set()
            release.wait(10)

    thread = threading.Thread(target=other)
    thread.start()
    entered.wait(10)
    with blasthreads.one_blas_thread():
        pass
    # This thread left first: the other one still runs with one BLAS thread.
    inside = blasthreads.blas_threads()
    release.set()
    thread.join()
    assert all(n == 1 for n in inside)
    assert blasthreads.blas_threads() == before


def test_encode_and_decode_run_one_blas_thread(monkeypatch):
    seen = []
    unit_vectors = normals.unit_vectors

    def spy(x):
        seen.append(blasthreads.blas_threads())
        return unit_vectors(x)

    monkeypatch.setattr(normals, "unit_vectors", spy)
    data = bandelets.encode(crease_normal_map(32), threshold=0.05, kind="normal-map")
    assert seen and all(n == 1 for counts in seen for n in counts)
    seen_decode = []
    decode_parsed = decoder.decode_parsed

    def spy_decode(*args, **kwargs):
        seen_decode.append(blasthreads.blas_threads())
        return decode_parsed(*args, **kwargs)

    monkeypatch.setattr(decoder, "decode_parsed", spy_decode)
    bandelets.decode(data)
    assert seen_decode and all(n == 1 for counts in seen_decode for n in counts)


@pytest.mark.parametrize("rows", [1, 2, 7, 13, 37])
def test_gram_matches_numpy(rows):
    f = np.random.default_rng(rows).standard_normal((rows, 1000))
    out = np.ones((rows, rows))
    loopfilter._gram(f, 900, out)  # only the first 900 columns count, added to what is there
    expected = 1.0 + f[:, :900] @ f[:, :900].T
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-9)
