"""GPU output (bandelets.io.gpu): mip chains, green convention, BC5 / BC7 / RGBA8 in KTX2 and DDS.

The files are read back by readers that share nothing with the writer: a KTX2 parser written here
from the KTX 2.0 specification, the DDS header parsed here and by Pillow, the blocks decoded by
Pillow (DDS level 0) and texture2ddecoder (every level).
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np
import pytest
import texture2ddecoder
from PIL import Image

from bandelets.io import gpu


def height_normals(height: int, width: int) -> np.ndarray:
    """Unit normals (H, W, 3) of a smooth height field: two bumps and a ridge, slopes up to 20 degrees."""
    y, x = np.mgrid[0:height, 0:width] / 16.0
    z = 1.2 * np.sin(x) * np.cos(0.7 * y) + 0.8 * np.exp(-((x - 2) ** 2 + (y - 2.5) ** 2)) + 0.3 * x
    gy, gx = np.gradient(z, 1 / 16.0)
    n = np.stack([-gx / 16, -gy / 16, np.ones_like(z) / 4], axis=2)
    return n / np.linalg.norm(n, axis=2, keepdims=True)


def angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((a * b).sum(axis=2), -1, 1)))


# --- an independent KTX2 reader, from the specification ---------------------------------------


def read_ktx2(data: bytes) -> dict:
    assert data[:12] == b"\xabKTX 20\xbb\r\n\x1a\n", "KTX2 identifier"
    fields = struct.unpack_from("<9I", data, 12)
    names = "vk_format type_size width height depth layers faces levels supercompression".split()
    info = dict(zip(names, fields, strict=True))
    dfd_offset, dfd_length, kvd_offset, kvd_length, sgd_offset, sgd_length = struct.unpack_from(
        "<4I2Q", data, 48
    )
    info["levels_index"] = [struct.unpack_from("<3Q", data, 80 + 24 * k) for k in range(info["levels"])]
    info["dfd"] = data[dfd_offset : dfd_offset + dfd_length]
    info["kvd"] = data[kvd_offset : kvd_offset + kvd_length]
    info["sgd"] = (sgd_offset, sgd_length)
    info["level_data"] = [data[o : o + n] for o, n, _ in info["levels_index"]]
    return info


def read_dds(data: bytes) -> dict:
    assert data[:4] == b"DDS "
    size, flags, height, width, pitch, depth, mips = struct.unpack_from("<7I", data, 4)
    assert size == 124
    pf_size, pf_flags, fourcc = struct.unpack_from("<II4s", data, 76)
    assert (pf_size, pf_flags, fourcc) == (32, 4, b"DX10")
    dxgi, dimension, _, array_size, _ = struct.unpack_from("<5I", data, 128)
    return dict(width=width, height=height, mips=mips, dxgi=dxgi, dimension=dimension, body=data[148:])


def decode(data: bytes, w: int, h: int, fmt: str) -> np.ndarray:
    """texture2ddecoder on whole blocks, cropped; RGBA (BC5: x, y)."""
    if fmt == "rgba8":
        return np.frombuffer(data, np.uint8).reshape(h, w, 4)
    pw, ph = -(-w // 4) * 4, -(-h // 4) * 4
    fn = texture2ddecoder.decode_bc5 if fmt == "bc5" else texture2ddecoder.decode_bc7
    bgra = np.frombuffer(fn(data, pw, ph), np.uint8).reshape(ph, pw, 4)[:h, :w]
    return bgra[..., [2, 1]] if fmt == "bc5" else bgra[..., [2, 1, 0, 3]]


def level_bytes(fmt: str, w: int, h: int) -> int:
    return w * h * 4 if fmt == "rgba8" else -(-w // 4) * -(-h // 4) * 16


# --- mips -------------------------------------------------------------------------------------


def test_mip_chain_unit_vectors_sizes_and_box_average() -> None:
    n = height_normals(64, 128)
    chain = gpu.mip_chain(n)
    assert [c.shape[:2] for c in chain] == [(64 >> k if k < 6 else 1, 128 >> k) for k in range(8)]
    for level in chain:
        assert np.allclose(np.linalg.norm(level, axis=2), 1, atol=1e-12)
    # Level k is the 2^k x 2^k mean of the unit vectors, renormalised (power-of-two sizes).
    for k in (1, 3):
        f = 2**k
        mean = n.reshape(64 // f, f, 128 // f, f, 3).mean(axis=(1, 3))
        assert np.allclose(chain[k], mean / np.linalg.norm(mean, axis=2, keepdims=True), atol=1e-12)
    # Not simply a subsampling: the mip differs from every other texel by a visible angle.
    assert angles(chain[1], n[::2, ::2]).max() > 0.5


def test_mip_chain_odd_sizes_weigh_every_texel() -> None:
    n = height_normals(45, 30)
    chain = gpu.mip_chain(n)
    assert [c.shape[:2] for c in chain] == [(45, 30), (22, 15), (11, 7), (5, 3), (2, 1), (1, 1)]
    assert all(np.allclose(np.linalg.norm(c, axis=2), 1, atol=1e-12) for c in chain)
    # The 1 x 1 level is the mean of all unit vectors, renormalised.
    mean = n.mean(axis=(0, 1))
    assert np.allclose(chain[-1][0, 0], mean / np.linalg.norm(mean), atol=1e-12)
    # The last row of an odd height reaches the last coarse row (a 2 x 2 box would drop it).
    bent = n.copy()
    bent[-1] = (1.0, 0.0, 0.0)
    changed = np.abs(gpu.mip_chain(bent)[1] - chain[1]).max(axis=(1, 2))
    assert changed[-1] > 0.01 and np.all(changed[:-1] == 0)


def test_mip_chain_of_xy_keeps_two_channels() -> None:
    n = height_normals(32, 32)
    chain_xy = gpu.mip_chain(n[..., :2])
    chain = gpu.mip_chain(n)
    assert all(c.shape[2] == 2 for c in chain_xy)
    assert np.allclose(chain_xy[2], chain[2][..., :2], atol=1e-12)


# --- green convention -------------------------------------------------------------------------


def test_flip_green_negates_y_only_and_twice_is_identity() -> None:
    n = height_normals(16, 24)
    f = gpu.flip_green(n)
    assert np.array_equal(f[..., 1], -n[..., 1])
    assert np.array_equal(f[..., [0, 2]], n[..., [0, 2]])
    assert np.array_equal(gpu.flip_green(f), n)
    samples = np.round((n + 1) * 127.5).astype(np.uint8)
    fs = gpu.flip_green(samples)
    assert np.array_equal(fs[..., 1], 255 - samples[..., 1]) and np.array_equal(gpu.flip_green(fs), samples)
    assert np.array_equal(fs[..., [0, 2]], samples[..., [0, 2]])


# --- blocks and containers --------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["bc5", "bc7", "rgba8"])
def test_ktx2_read_back_independently(tmp_path: Path, fmt: str) -> None:
    n = height_normals(40, 72)  # 40 x 72: levels 20 x 36, 10 x 18, 5 x 9, 2 x 4, 1 x 2, 1 x 1
    path = tmp_path / "map.ktx2"
    result = gpu.export(path, n, fmt)
    data = path.read_bytes()
    assert result.file_bytes == len(data) and result.container == "ktx2"
    info = read_ktx2(data)
    assert info["vk_format"] == {"bc5": 141, "bc7": 145, "rgba8": 37}[fmt]
    assert (info["width"], info["height"], info["depth"], info["layers"], info["faces"]) == (72, 40, 0, 0, 1)
    assert info["type_size"] == 1 and info["supercompression"] == 0 and info["sgd"] == (0, 0)
    assert info["levels"] == 7
    # The DFD: its total size, a Khronos basic block of the right colour model and block size.
    dfd = info["dfd"]
    total, word0, version, block_size = struct.unpack_from("<IIHH", dfd)
    model, _, transfer, _ = dfd[12:16]
    assert total == len(dfd) and word0 == 0 and version == 2 and block_size == total - 4
    assert model == {"bc5": 132, "bc7": 134, "rgba8": 1}[fmt] and transfer == 1
    assert dfd[16:20] == (bytes([3, 3, 0, 0]) if fmt != "rgba8" else bytes(4))
    assert b"KTXwriter\x00" in info["kvd"]
    # Levels: stored smallest first, aligned, of the size the format gives, within the file.
    offsets = [o for o, _, _ in info["levels_index"]]
    assert offsets == sorted(offsets, reverse=True)
    alignment = 4 if fmt == "rgba8" else 16
    chain = gpu.mip_chain(n)
    for k, ((offset, length, raw), level) in enumerate(zip(info["levels_index"], chain, strict=True)):
        h, w = level.shape[:2]
        assert offset % alignment == 0 and offset + length <= len(data) and raw == length
        assert length == level_bytes(fmt, w, h)
        decoded = decode(info["level_data"][k], w, h, fmt)
        # The decoded blocks match what the summary reports, level by level.
        reported = result.level_errors[k]
        measured = angles(
            level, gpu.to_unit(decoded[..., :2] / 127.5 - 1 if fmt == "bc5" else decoded[..., :3] / 127.5 - 1)
        )
        assert measured.mean() == pytest.approx(reported.mean, abs=1e-9)
        assert np.percentile(measured, 99) == pytest.approx(reported.p99, abs=1e-9)
    assert result.error == result.level_errors[0]
    # What each format adds to a smooth map, and that BC5 keeps x, y better than BC7 keeps x, y, z.
    assert result.error.mean < {"bc5": 0.3, "bc7": 0.6, "rgba8": 0.25}[fmt]


@pytest.mark.parametrize("fmt", ["bc5", "bc7", "rgba8"])
def test_dds_read_back_by_pillow_and_header(tmp_path: Path, fmt: str) -> None:
    n = height_normals(40, 72)
    path = tmp_path / "map.dds"
    result = gpu.export(path, n, fmt)
    ktx = gpu.export(tmp_path / "map.ktx2", n, fmt)
    info = read_dds(path.read_bytes())
    assert info["dxgi"] == {"bc5": 83, "bc7": 98, "rgba8": 28}[fmt] and info["dimension"] == 3
    assert (info["width"], info["height"], info["mips"]) == (72, 40, 7)
    # The DDS body is the KTX2 levels, largest first, packed.
    ktx_levels = read_ktx2((tmp_path / "map.ktx2").read_bytes())["level_data"]
    assert info["body"] == b"".join(ktx_levels)
    assert ktx.level_errors == result.level_errors
    # Pillow's own BCn decoder on level 0 gives the error the summary reports.
    with Image.open(path) as image:
        assert image.size == (72, 40)
        pixels = np.asarray(image)
    decoded = pixels[..., :2] if fmt == "bc5" else pixels[..., :3]
    pillow = gpu.angular_error_added(n, decoded)
    assert pillow.mean == pytest.approx(result.error.mean, abs=1e-9)
    assert pillow.p99 == pytest.approx(result.error.p99, abs=1e-9)
    assert np.array_equal(decoded, gpu.decode_blocks(ktx_levels[0], 72, 40, fmt)[..., : decoded.shape[2]])


def test_single_level_and_default_format(tmp_path: Path) -> None:
    n = height_normals(20, 12)
    result = gpu.export(tmp_path / "one.ktx2", n[..., :2], mips=False)
    info = read_ktx2((tmp_path / "one.ktx2").read_bytes())
    assert result.fmt == "bc5" and info["levels"] == 1 and info["vk_format"] == 141
    assert gpu.export(tmp_path / "one.dds", n, mips=False).fmt == "bc7"
    # A file object: the container named, the same bytes as the path.
    stream = io.BytesIO()
    gpu.export(stream, n[..., :2], mips=False, container="ktx2")
    assert stream.getvalue() == (tmp_path / "one.ktx2").read_bytes()


def test_angular_error_added_measures_a_known_rotation() -> None:
    n = height_normals(16, 16)
    assert gpu.angular_error_added(n, n).mean == pytest.approx(0, abs=1e-6)
    t = np.radians(5.0)  # every vector of a flat map tilted by 5 degrees
    flat = np.zeros_like(n)
    flat[..., 2] = 1
    tilted = flat.copy()
    tilted[..., 0], tilted[..., 2] = np.sin(t), np.cos(t)
    error = gpu.angular_error_added(flat, tilted)
    assert error.mean == pytest.approx(5.0, abs=1e-9) and error.p99 == pytest.approx(5.0, abs=1e-9)


def test_bad_input_is_refused_in_one_line() -> None:
    n = height_normals(8, 8)
    with pytest.raises(ValueError, match="unknown GPU format"):
        gpu.compress(n, "bc1")
    with pytest.raises(ValueError, match="shape"):
        gpu.mip_chain(n[..., 0])
    with pytest.raises(ValueError, match="needs 64 bytes"):
        gpu.write_ktx2("unused.ktx2", [b"\0" * 60], 8, 8, "bc5")
    with pytest.raises(ValueError, match="1 to 4 levels"):
        gpu.write_dds("unused.dds", [b"\0" * 64] * 5, 8, 8, "bc5")
    with pytest.raises(ValueError, match=r"\.ktx2 or \.dds"):
        gpu.export("out.png", n)
