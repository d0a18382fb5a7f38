"""Compatibility: the golden .bdl files of tests/data keep decoding to the same arrays.

The files, their inputs and golden.json come from tests/data/make_golden.py (see
tests/data/README.md). A format change must keep these tests passing or bump
FORMAT_VERSION.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import struct
import zlib
from pathlib import Path

import pytest

import bandelets
from bandelets.format.fields import FORMAT_VERSION, FormatError

DATA = Path(__file__).resolve().parent / "data"
GOLDEN = json.loads((DATA / "golden.json").read_text())
NAMES = sorted(GOLDEN["files"])


def _maker():
    spec = importlib.util.spec_from_file_location("make_golden", DATA / "make_golden.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


make_golden = _maker()


def test_the_golden_files_are_the_ones_listed():
    assert GOLDEN["format_version"] == FORMAT_VERSION, (
        "FORMAT_VERSION changed: regenerate tests/data with make_golden.py and keep the old files refused"
    )
    assert sorted(p.name for p in DATA.glob("*.bdl")) == NAMES == sorted(make_golden.GOLDEN)
    for name in NAMES:
        data = (DATA / name).read_bytes()
        assert hashlib.sha256(data).hexdigest() == GOLDEN["files"][name]["file_sha256"], name


@pytest.mark.parametrize("name", NAMES)
def test_golden_file_decodes_to_the_stored_checksum(name):
    expected = GOLDEN["files"][name]
    decoded = bandelets.decode((DATA / name).read_bytes())
    assert list(decoded.shape) == expected["decoded_shape"]
    assert make_golden.decoded_sha256(decoded) == expected["decoded_sha256"], (
        f"{name} no longer decodes to the same array: the decoder changed the format; "
        "restore compatibility or bump FORMAT_VERSION"
    )


@pytest.mark.parametrize("name", NAMES)
def test_reencoding_the_golden_input_gives_the_same_bytes(name):
    make, options = make_golden.GOLDEN[name]
    assert options == GOLDEN["files"][name]["options"]
    data = bandelets.encode(make(), **options)
    assert data == (DATA / name).read_bytes(), (
        f"encoding the input of {name} no longer gives the committed file. If the encoder changed on "
        "purpose (a better search), check that the committed file still decodes (test above) and "
        "regenerate with python tests/data/make_golden.py"
    )


@pytest.mark.parametrize("version", [0, 1, FORMAT_VERSION + 1, 255])
def test_another_version_is_refused_by_name(version):
    body = bytearray((DATA / NAMES[0]).read_bytes()[:-4])
    body[4] = version
    data = bytes(body) + struct.pack("<I", zlib.crc32(bytes(body)))
    with pytest.raises(FormatError, match=f"version {version} is not supported"):
        bandelets.decode(data)
