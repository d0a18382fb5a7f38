"""The Examples of the package's docstrings run and print what they say (as PyWavelets' test_doc)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import bandelets

#: Every module of the package but the one that runs the command line on import.
MODULES = ["bandelets"] + [
    m.name for m in pkgutil.walk_packages(bandelets.__path__, "bandelets.") if m.name != "bandelets.__main__"
]


def test_the_public_functions_show_examples():
    documented = {name for name in bandelets.__all__ if ">>>" in (getattr(bandelets, name).__doc__ or "")}
    assert documented >= {"encode", "decode", "forward"}


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    flags = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS
    result = doctest.testmod(module, optionflags=flags, report=True, verbose=False)
    assert result.failed == 0, f"{result.failed} of the examples of {name} failed (see the output above)"
