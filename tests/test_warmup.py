"""The first run's warm-up process (bandelets.codec.warmup, started by bandelets.runtime.compilation)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from bandelets import decode
from bandelets.codec.warmup import FILES
from bandelets.format.header import unpack
from bandelets.runtime.compilation import WARM_UP


def test_the_files_are_of_the_current_format_and_cover_the_decoder():
    # A change of the format makes them unreadable: `python -m bandelets.codec.warmup --make`.
    headers = {path.stem: unpack((FILES / path.name).read_bytes())[0] for path in FILES.glob("*.bdl")}
    assert set(headers) == {"lifted", "filtered", "riesz", "lossless"}
    assert headers["lifted"].lifting and headers["lifted"].restoration
    assert headers["filtered"].loop_filter is not None
    assert headers["riesz"].riesz
    assert headers["lossless"].transform == "lossless"
    for name in headers:
        assert np.all(np.isfinite(decode((FILES / f"{name}.bdl").read_bytes())))


def _run(code: str, **env) -> subprocess.CompletedProcess:
    prelude = "import subprocess\nfrom numba import njit\nfrom bandelets.runtime import compilation\n"
    # The process started is named on stdout instead of started.
    prelude += "subprocess.Popen = lambda args, **kw: print(*args[1:], kw['env']['" + WARM_UP + "'])\n"
    environment = {k: v for k, v in os.environ.items() if k != WARM_UP} | env
    return subprocess.run(
        [sys.executable, "-c", prelude + code], capture_output=True, text=True, timeout=120, env=environment
    )


def test_the_first_compilation_starts_the_warm_up_once():
    code = "compilation.announce(quiet=True, warm=True)\nnjit(lambda x: x + 1)(1)\nnjit(lambda x: x + 2)(1)\n"
    started = _run(code)
    assert (started.returncode, started.stdout, started.stderr) == (0, "-m bandelets.codec.warmup 0\n", "")
    assert _run(code, **{WARM_UP: "0"}).stdout == ""  # asked not to
    assert _run(code.replace("warm=True", "warm=False")).stdout == ""


def test_the_warm_up_runs():
    done = subprocess.run(
        [sys.executable, "-m", "bandelets.codec.warmup"], capture_output=True, text=True, timeout=600
    )
    assert (done.returncode, done.stderr) == (0, "")


@pytest.mark.parametrize("compiling", [None, "dead"])
def test_the_warm_up_waits_only_for_a_process_that_compiles(monkeypatch, compiling):
    from bandelets.codec import warmup
    from bandelets.coding.coefficients import _coefficients
    from bandelets.runtime.compilation import COMPILING

    index = _coefficients._cache._cache_file
    monkeypatch.setattr(index, "_load_index", lambda: {})  # the coder not in the cache yet

    def sleep(seconds):
        raise AssertionError("waited")

    monkeypatch.setattr(warmup.time, "sleep", sleep)
    if compiling is None:  # run by hand: nobody compiles it
        monkeypatch.delenv(COMPILING, raising=False)
    else:  # its parent gone
        child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True)
        monkeypatch.setenv(COMPILING, child.stdout.decode().strip())
    warmup._await_coefficient_coder()  # returns at once
    monkeypatch.setenv(COMPILING, str(os.getpid()))  # a live one: it waits
    with pytest.raises(AssertionError, match="waited"):
        warmup._await_coefficient_coder()
