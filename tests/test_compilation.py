"""The first run says that it compiles (bandelets.runtime.compilation), in a process of its own."""

from __future__ import annotations

import subprocess
import sys

from bandelets.runtime import compilation


def _run(code: str) -> subprocess.CompletedProcess:
    prelude = "import sys\nfrom numba import njit\nfrom bandelets.runtime import compilation\n"
    return subprocess.run([sys.executable, "-c", prelude + code], capture_output=True, text=True, timeout=120)


def test_the_first_compilation_is_announced_once():
    done = _run(
        "f = njit(lambda x: x * 3)\n"
        "f(1)\n"  # compiled before anyone listens
        "compilation.announce()\n"
        "compilation.announce()\n"  # listens once
        "f(2)\n"  # already compiled: nothing to say
        "print('before', file=sys.stderr)\n"
        "njit(lambda x: x + 1)(1)\n"
        "njit(lambda x: x + 2)(1)\n"
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == f"before\n{compilation.MESSAGE}\n"


def test_a_closed_stderr_does_not_fail_the_compilation():
    done = _run("compilation.announce()\nsys.stderr.close()\nnjit(lambda x: x + 1)(1)\nprint('compiled')\n")
    assert (done.returncode, done.stdout) == (0, "compiled\n")


def test_quiet_commands_say_nothing():
    # What `bandelets encode -q` / `decode -q` call before their work (cli._working).
    quiet = _run("from bandelets.apps import cli\ncli._working(quiet=True)\nnjit(lambda x: x + 1)(1)\n")
    loud = _run("from bandelets.apps import cli\ncli._working()\nnjit(lambda x: x + 1)(1)\n")
    assert (quiet.returncode, quiet.stderr) == (0, "")
    assert (loud.returncode, loud.stderr) == (0, f"{compilation.MESSAGE}\n")


def test_kernels_cached_from_other_sources_are_deleted(tmp_path):
    from bandelets.runtime.kernelcache import STAMP, purge_stale_kernels

    package = tmp_path / "site-packages" / "pkg"
    (package / "__pycache__").mkdir(parents=True)
    (tmp_path / ".git").mkdir()  # pyenv's Pythons live in a git repository: no matter
    (package / "kernels.py").write_text("A = 1\n")
    cached = [package / "__pycache__" / f"kernels.f-1.py311.{suffix}" for suffix in ("nbi", "1.nbc")]
    for path in cached:
        path.write_bytes(b"old")
    assert purge_stale_kernels(package)  # no stamp yet: made by an earlier install
    assert not any(path.exists() for path in cached)
    assert (package / "__pycache__" / STAMP).exists()
    for path in cached:  # compiled again from these sources
        path.write_bytes(b"new")
    assert not purge_stale_kernels(package)
    assert all(path.exists() for path in cached)
    (package / "kernels.py").write_text("A = 2\n")  # a new version installed over it
    assert purge_stale_kernels(package)
    assert not any(path.exists() for path in cached)
    # A source checkout (src layout, beside the pyproject.toml) is left alone.
    (tmp_path / "pyproject.toml").write_text("")
    (package / "kernels.py").write_text("A = 3\n")
    cached[0].write_bytes(b"new")
    assert not purge_stale_kernels(package)
    assert cached[0].exists()
