"""The .bdl container: header, validation and robustness of decode() to damaged files."""

from __future__ import annotations

import struct
import subprocess
import sys
import textwrap
import typing
import zlib
from dataclasses import replace

import numpy as np
import pytest
from headerints import integer_count, leb128, read_integers

import bandelets
from bandelets.codec.options import EncodeOptions
from bandelets.format.fields import (
    FORMAT_VERSION,
    KINDS,
    MAGIC,
    MAX_THRESHOLD,
    MIN_THRESHOLD,
    NORMAL_MAP_WEIGHT,
    TRANSFORMS_1D,
    WAVELETS,
    FormatError,
    Kind,
    Transform1D,
    Wavelet,
)
from bandelets.format.header import HEADER_BYTES, Header, implied_options, pack, streams_offset, unpack
from bandelets.format.levels import group_count

FIXED_SIZE = 14  # fixed fields, before the five LEB128 integers (sides, stream lengths)
GEOMETRY_SIZE = 5  # options of a geometry image, before its LEB128 vertex count


#: A normal map that is an octahedral geometry image (format version 14).
FOLDED = Header(
    height=64,
    width=64,
    channels=3,
    kind="normal-map",
    transform="bandelet",
    wavelet="cdf97",
    levels=5,
    threshold=0.05,
    frames=True,
    normal_weight=NORMAL_MAP_WEIGHT,
    lifting=2,
    folded=True,
)


def _with_crc(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body))


def _patched(data: bytes, offset: int, fmt: str, value) -> bytes:
    """``data`` with one header field replaced and a valid CRC again."""
    b = bytearray(data[:-4])
    struct.pack_into(fmt, b, offset, value)
    return _with_crc(bytes(b))


def _bits(data: bytes, offset: int, mask: int, value: int) -> bytes:
    """``data`` with the bits ``mask`` of byte ``offset`` set to ``value`` (shifted into them)."""
    low = (mask & -mask).bit_length() - 1
    return _patched(data, offset, "<B", data[offset] & ~mask | value << low)


def _with_integers(data: bytes, start: int, values: dict[int, int], count: int | None = None) -> bytes:
    """``data`` with the ``count`` LEB128 integers from ``start`` rewritten (``values``: index ->
    value; 0 height, 1 width, 2 to 4 the stream lengths) and a valid CRC again."""
    old, end = read_integers(data, start, count or integer_count(data))
    new = [values.get(i, v) for i, v in enumerate(old)]
    return _with_crc(data[:start] + b"".join(map(leb128, new)) + data[end:-4])


@pytest.fixture(scope="module")
def small_file():
    """A small gray bandelet file and the image it came from."""
    from conftest import straight_edge

    x = straight_edge(shape=(24, 40)) + 0.05 * np.random.default_rng(3).standard_normal((24, 40))
    return bandelets.encode(x, threshold=0.08), x.shape


@pytest.fixture(scope="module")
def normal_file():
    from bandelets.samples import crease_normal_map

    return bandelets.encode(crease_normal_map(32), threshold=0.03, kind="normal-map")


def test_format_error_is_a_value_error():
    assert issubclass(FormatError, ValueError)
    assert bandelets.FormatError is FormatError


def test_the_types_of_the_names_are_the_coded_names():
    assert tuple(Kind) == KINDS
    assert typing.get_args(Wavelet) == WAVELETS
    assert typing.get_args(Transform1D) == TRANSFORMS_1D


@pytest.mark.parametrize(
    "header",
    [
        Header(
            height=24,
            width=40,
            channels=1,
            kind="image",
            transform="bandelet",
            wavelet="cdf97",
            levels=2,
            threshold=0.08,
            depth=0,
            transform_1d="alpert2",
        ),
        Header(
            height=16384,
            width=3,
            channels=3,
            kind="geometry-image",
            transform="wavelet",
            wavelet="db8",
            levels=6,
            threshold=1e-9,
            depth=16,
            transform_1d="haar",
        ),
        Header(
            height=1,
            width=2,
            channels=2,
            kind="normal-map",
            transform="bandelet",
            wavelet="haar",
            levels=1,
            threshold=12.5,
            depth=8,
            transform_1d="alpert2",
        ),
        Header(
            height=1,
            width=2,
            channels=2,
            kind="normal-map",
            transform="bandelet",
            wavelet="haar",
            levels=1,
            threshold=12.5,
            depth=16,
            layout="xy",
        ),
        Header(
            height=1,
            width=2,
            channels=2,
            kind="normal-map",
            transform="bandelet",
            wavelet="haar",
            levels=1,
            threshold=12.5,
            layout="rg",
        ),
        Header(
            height=3,
            width=2,
            channels=3,
            kind="normal-map",
            transform="wavelet",
            wavelet="cdf97",
            levels=1,
            threshold=0.5,
            depth=0,
            transform_1d="haar",
            frames=True,
            normal_weight=0.35,
        ),
        Header(
            height=64,
            width=64,
            channels=3,
            kind="geometry-image",
            transform="bandelet",
            wavelet="cdf97",
            levels=6,
            threshold=0.01,
            depth=0,
            transform_1d="alpert2",
            extension="spherical",
            frames=True,
            normal_weight=2.5,
        ),
        FOLDED,
    ],
)
def test_header_round_trip(header):
    streams = (b"ab", b"", b"\x00\xff" * 50)
    data = pack(header, streams)
    assert data[:4] == MAGIC
    assert data[4] == FORMAT_VERSION
    extra = GEOMETRY_SIZE + 1 if header.kind == "geometry-image" else 0  # 1: the vertices, 0
    # Format version 19: the segments of every group of levels, all in the last one here.
    segments = ((0, 0, 0),) * (group_count(header.levels, header.transform) - 1) + (tuple(map(len, streams)),)
    lengths = [segments[0][2]] + [n for group in segments[1:] for n in group]  # group 0: coefficients
    integers = len(b"".join(map(leb128, (header.height, header.width, *lengths))))
    assert len(data) == FIXED_SIZE + integers + extra + sum(map(len, streams)) + 4
    assert streams_offset(data) == FIXED_SIZE + integers + extra
    got, got_streams = unpack(data)
    assert got == replace(header, segments=segments)
    assert got_streams == streams


def test_options_a_file_does_not_store_must_be_the_implied_ones():
    """A normal map of three channels is always coded in local frames of weight NORMAL_MAP_WEIGHT,
    any other kind but a geometry image never: the header cannot say otherwise."""
    assert implied_options("normal-map", 3) == {"frames": True, "normal_weight": NORMAL_MAP_WEIGHT}
    for header in (
        Header(
            height=8,
            width=8,
            channels=3,
            kind="normal-map",
            transform="bandelet",
            wavelet="cdf97",
            levels=1,
            threshold=0.1,
        ),
        Header(
            height=8,
            width=8,
            channels=2,
            kind="normal-map",
            transform="bandelet",
            wavelet="cdf97",
            levels=1,
            threshold=0.1,
            frames=True,
        ),
        Header(
            height=8,
            width=8,
            channels=1,
            kind="image",
            transform="bandelet",
            wavelet="cdf97",
            levels=1,
            threshold=0.1,
            extension="spherical",
        ),
    ):
        with pytest.raises(ValueError, match="no choice"):
            pack(header, (b"", b"", b""))


@pytest.mark.parametrize(
    "changes",
    [
        {"channels": 2, "frames": False, "normal_weight": 1.0},
        {"width": 32},
        {"height": 48, "width": 48},  # padded at 5 levels
        {"kind": "image", "frames": False, "normal_weight": 1.0},
    ],
)
def test_only_a_square_unpadded_normal_map_of_three_channels_is_folded(changes):
    pack(FOLDED, (b"", b"", b""))
    with pytest.raises(ValueError, match="folded"):
        pack(replace(FOLDED, **changes), (b"", b"", b""))


def test_folded_flag_on_a_normal_map_that_cannot_be_folded_is_a_format_error(normal_file):
    """The crease map of 32 x 32 is coded as two channels: it cannot be folded."""
    with pytest.raises(FormatError, match="folded"):
        bandelets.decode(_patched(normal_file, 9, "<B", normal_file[9] + 128))


def test_bad_magic(small_file):
    data, _ = small_file
    with pytest.raises(FormatError, match="magic"):
        unpack(b"PNG\x1a" + data[4:])
    with pytest.raises(FormatError, match="magic"):
        bandelets.decode(b"")


def test_wrong_version_is_named(small_file):
    data, _ = small_file
    bad = _patched(data, 4, "<B", FORMAT_VERSION + 1)
    with pytest.raises(FormatError, match=f"version {FORMAT_VERSION + 1}"):
        bandelets.decode(bad)


def test_crc_mismatch(small_file):
    data, _ = small_file
    b = bytearray(data)
    b[len(b) // 2] ^= 0x10
    with pytest.raises(FormatError, match="CRC"):
        bandelets.decode(bytes(b))
    with pytest.raises(FormatError, match="CRC"):
        bandelets.decode(data[:-1] + bytes([data[-1] ^ 1]))


def test_truncated_header(small_file):
    data, _ = small_file
    with pytest.raises(FormatError, match="truncated"):
        unpack(data[: HEADER_BYTES - 1])


@pytest.mark.parametrize(
    ("offset", "mask", "value", "words"),
    [
        (5, 255, 9, "kind"),
        (6, 3, 3, "transform"),
        (6, 3, 2, "lossless file"),
        (6, 28, 7, "wavelet"),
        (6, 192, 1, "layout"),  # x, y layout of a gray image
        (6, 192, 3, "layout"),
        (7, 7, 0, "levels"),
        (7, 7, 7, "levels"),
        (7, 96, 3, "depth"),
        (7, 128, 1, "green convention"),  # format 19: the top bit is a normal map's green
        (8, 127, 101, "restoration iterations"),
        (9, 31, 4, "directional levels"),
        (9, 128, 1, "folded"),  # a gray image
    ],
)
def test_absurd_fields_are_format_errors(small_file, offset, mask, value, words):
    data, _ = small_file
    with pytest.raises(FormatError, match=words):
        bandelets.decode(_bits(data, offset, mask, value))


@pytest.mark.parametrize(
    "threshold", [0.0, -1.0, float("nan"), float("inf"), MIN_THRESHOLD / 2, MAX_THRESHOLD * 2, 3e38]
)
def test_thresholds_out_of_range_are_format_errors(small_file, threshold):
    with pytest.raises(FormatError, match="threshold"):
        bandelets.decode(_patched(small_file[0], 10, "<f", threshold))


@pytest.mark.parametrize(
    ("values", "words"),
    [
        ({0: 2**31}, "exceeds"),  # height
        ({1: 100_000}, "exceeds"),  # width
        ({0: 0}, "exceeds"),
        ({2: 10**6}, "stream lengths"),
        ({2: 0}, "stream lengths"),  # the approximation's coefficients (format 19)
        ({0: 2**32}, "exceeds 2\\*\\*32"),
    ],
)
def test_absurd_integers_are_format_errors(small_file, values, words):
    with pytest.raises(FormatError, match=words):
        bandelets.decode(_with_integers(small_file[0], FIXED_SIZE, values))


def test_too_many_samples_is_a_format_error(small_file):
    """Sides within the limit, too many samples: 16384 x 16384 x 4 channels."""
    data = _with_integers(_bits(small_file[0], 7, 24, 3), FIXED_SIZE, {0: 16384, 1: 16384})
    with pytest.raises(FormatError, match="samples"):
        bandelets.decode(data)


def test_malformed_integers_are_format_errors(small_file):
    data = small_file[0]
    height = read_integers(data, FIXED_SIZE, 1)[0][0]  # 24: one byte
    for bad, words in [
        (bytes([height | 128, 0]), "needless byte"),
        (b"\x80" * 5 + b"\x01", "over 5 bytes"),
    ]:
        with pytest.raises(FormatError, match=words):
            bandelets.decode(_with_crc(data[:FIXED_SIZE] + bad + data[FIXED_SIZE + 1 : -4]))


def test_size_limits_are_configurable(small_file):
    data, shape = small_file
    with pytest.raises(FormatError, match="exceeds"):
        bandelets.decode(data, max_side=shape[1] - 1)
    with pytest.raises(FormatError, match="exceeds"):
        bandelets.decode(data, max_samples=shape[0] * shape[1] - 1)
    assert bandelets.decode(data, max_side=shape[1], max_samples=shape[0] * shape[1]).shape == shape


def _decodes_or_format_error(data, shape):
    try:
        out = bandelets.decode(data)
    except FormatError:
        return False
    assert out.shape == shape
    return True


def test_every_truncation_is_a_format_error(small_file):
    data, shape = small_file
    for n in range(len(data)):
        assert not _decodes_or_format_error(data[:n], shape), n


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_random_bit_flips(small_file):
    data, shape = small_file
    rng = np.random.default_rng(7)
    for bit in rng.integers(0, 8 * len(data), 200):
        b = bytearray(data)
        b[bit // 8] ^= 1 << (bit % 8)
        # The CRC catches every single-bit error.
        assert not _decodes_or_format_error(bytes(b), shape), bit


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("which", ["small", "normal"])
def test_bit_flips_in_the_streams_behind_a_valid_crc(small_file, normal_file, which):
    """Damage the CRC cannot see (a valid CRC recomputed): the decoder itself must cope."""
    data, shape = small_file if which == "small" else (normal_file, (32, 32, 3))
    rng = np.random.default_rng(11)
    outcomes = set()
    for bit in rng.integers(8 * streams_offset(data), 8 * (len(data) - 4), 150):
        b = bytearray(data[:-4])
        b[bit // 8] ^= 1 << (bit % 8)
        outcomes.add(_decodes_or_format_error(_with_crc(bytes(b)), shape))
    assert True in outcomes  # most flips still decode, to something else


@pytest.mark.parametrize(("kind", "channels"), [(1, 1), (1, 4), (2, 2)])
def test_vector_label_on_a_file_of_the_wrong_channel_count_is_a_format_error(kind, channels):
    # A valid image file whose kind byte says normal-map or geometry-image (valid CRC): a
    # normal map has 3 channels or 2 (z rebuilt), a geometry image 3.
    x = np.random.default_rng(5).random((16, 16, channels))
    bad = _patched(bandelets.encode(x, threshold=0.1), 5, "<B", kind)
    with pytest.raises(FormatError):
        bandelets.decode(bad)


def test_huge_threshold_does_not_crash_the_decoder(tmp_path):
    # In a subprocess: the failure mode is a crash of the interpreter.
    script = textwrap.dedent(
        """
        import struct, sys, zlib
        import numpy as np
        import bandelets
        y, x = np.mgrid[0:64, 0:64]
        image = np.tanh((np.cos(0.5) * (y - 32.2) - np.sin(0.5) * (x - 32.3)) / 1.5)
        image = image + 0.02 * np.random.default_rng(0).standard_normal(image.shape)
        data = bytearray(bandelets.encode(image, threshold=0.02)[:-4])
        struct.pack_into("<f", data, 10, 3e38)
        data = bytes(data) + struct.pack("<I", zlib.crc32(bytes(data)))
        try:
            out = bandelets.decode(data)
        except bandelets.FormatError:
            print("FormatError")
        else:
            print("decoded", out.shape, bool(np.isfinite(out).all()))
        """
    )
    done = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert done.returncode == 0, f"decoder process died with status {done.returncode}"
    assert done.stdout.startswith(("FormatError", "decoded (64, 64)"))


@pytest.fixture(scope="module")
def geometry_file():
    """A small spherical geometry image coded with local frames and the spherical extension."""
    from bandelets.surfaces import octahedral

    p = octahedral.square_to_sphere(octahedral.grid(16))
    return bandelets.encode(p, threshold=0.01, kind="geometry-image", frames=True, extension="spherical")


def _levels(data: bytes, levels: int) -> bytes:
    """``data`` at another count of wavelet levels, more groups of empty segments in front (format 19)."""
    old, end = read_integers(data, FIXED_SIZE, integer_count(data))
    patched = _bits(data, 7, 7, levels)
    new = old[:2] + [0] * (integer_count(patched) - len(old)) + old[2:]
    return _with_crc(patched[:FIXED_SIZE] + b"".join(map(leb128, new)) + data[end:-4])


def _options_at(data: bytes) -> int:
    """Where a geometry image's options start: after the five integers of its header."""
    return read_integers(data, FIXED_SIZE, integer_count(data))[1]


def test_geometry_options_are_read_back(geometry_file):
    header, _ = unpack(geometry_file)
    assert (header.extension, header.frames, header.normal_weight) == ("spherical", True, 2.0)
    assert header.mesh_vertices == 0  # an image made from no mesh
    more = _with_integers(geometry_file, _options_at(geometry_file) + GEOMETRY_SIZE, {0: 6002}, 1)
    assert unpack(more)[0].mesh_vertices == 6002


def test_mesh_vertices_belong_to_geometry_images():
    header = unpack(bandelets.encode(np.zeros((8, 8)), threshold=1.0))[0]
    with pytest.raises(ValueError, match="mesh vertices"):
        pack(replace(header, mesh_vertices=100), (b"", b"", b""))
    with pytest.raises(ValueError, match="mesh vertices apply to geometry images only"):
        EncodeOptions(kind="image", mesh_vertices=5)
    for bad in (3, -1, 2**32, 4.0):
        with pytest.raises(ValueError, match="mesh_vertices"):
            EncodeOptions(kind="geometry-image", mesh_vertices=bad)


@pytest.mark.parametrize(
    ("offset", "fmt", "value", "words"),
    [
        (0, "<B", 6, "extension code"),  # frames on, extension 4
        (1, "<f", 0.0, "normal weight"),
        (1, "<f", 65.0, "normal weight"),
        (1, "<f", float("nan"), "normal weight"),
        (1, "<f", float("-inf"), "normal weight"),
        (5, "<B", 3, "source mesh of 3 vertices"),
    ],
)
def test_absurd_geometry_options_are_format_errors(geometry_file, offset, fmt, value, words):
    offset += _options_at(geometry_file)
    with pytest.raises(FormatError, match=words):
        bandelets.decode(_patched(geometry_file, offset, fmt, value))


@pytest.mark.parametrize(
    "patch",
    [
        lambda data: _bits(data, 6, 28, 1),  # haar
        lambda data: _with_integers(data, FIXED_SIZE, {1: 8}),  # not square
        lambda data: _levels(data, 5),  # 16 is not a multiple of 2**5
    ],
)
def test_spherical_extension_of_another_image_is_a_format_error(geometry_file, patch):
    with pytest.raises(FormatError, match="spherical extension"):
        bandelets.decode(patch(geometry_file))


def test_normal_weight_without_frames_is_a_format_error(geometry_file):
    with pytest.raises(FormatError, match="without local frames"):
        bandelets.decode(_bits(geometry_file, _options_at(geometry_file), 2, 0))


def test_geometry_file_truncated_in_its_options(geometry_file):
    start = _options_at(geometry_file)
    for end in range(start, start + GEOMETRY_SIZE + 1):
        with pytest.raises(FormatError):
            bandelets.decode(_with_crc(geometry_file[:end]))
