"""The decode command's outputs beyond one image (issue 39): a coarser level (``--level``), every level
(``--mips``), GPU files (.ktx2, .dds in BC5, BC7 or RGBA8 through :func:`bandelets.io.gpu.export`)
and the green convention (``--green``).

Naming of ``--mips`` for image outputs: ``OUT.png`` becomes ``OUT-0.png`` (the full decode, or the
``--level`` asked), ``OUT-1.png``, ... each half the size of the one before, down to 1 x 1. A normal
map's mips are the box averages of its decoded unit vectors, renormalised
(:func:`bandelets.io.gpu.mip_chain`: sides halved and rounded down), as a GPU file holds them: the
whole file is read for level 0 anyway, and they are closer to the mips of the original than the
images a prefix decodes to (``benchmarks/mip_levels.py``). Other images: the levels the file holds
decoded from it (:mod:`bandelets.codec.levels`, sides rounded up), then 2 x 2 box averages.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is not imported before a command runs (bandelets.apps.cli)
    import numpy as np

__all__ = [
    "add_batch_options",
    "add_decode_options",
    "add_green_option",
    "decoded_levels",
    "flip_green",
    "gpu_suffix",
    "ship",
    "write_outputs",
]

GPU_SUFFIXES = (".ktx2", ".dds")


def add_green_option(p: argparse.ArgumentParser, decoding: bool) -> None:
    """``--green up|down``: the green convention of a normal map (OpenGL: up; DirectX: down)."""
    p.add_argument(
        "--green",
        choices=("up", "down"),
        help="normal maps: the green (y) convention, up (OpenGL) or down (DirectX); "
        + (
            "the map is written in it, y flipped if the file holds the other (default: the file's)"
            if decoding
            else "stored in the file (default up)"
        ),
    )


def add_decode_options(p: argparse.ArgumentParser) -> None:
    """The options of ``bandelets decode`` this module serves."""
    p.add_argument(
        "--level",
        type=int,
        default=0,
        metavar="K",
        help="decode the image at 1/2^K of the size from the first bytes of the file (no restoration)",
    )
    p.add_argument(
        "--mips",
        action="store_true",
        help="every level down to 1 x 1, renormalised: OUT-0.png, OUT-1.png, ... (in a .ktx2 or .dds)",
    )
    p.add_argument(
        "--gpu",
        choices=("bc5", "bc7", "rgba8"),
        help="block format of a .ktx2 or .dds output (default bc5 for x, y maps, bc7 for three channels)",
    )
    add_green_option(p, decoding=True)


def add_batch_options(p: argparse.ArgumentParser) -> None:
    """``bandelets batch --to FORMAT [--mips] [--gpu] [--green]``: each .bdl file decoded beside it."""
    p.add_argument(
        "--to",
        choices=("ktx2", "dds", "png", "tif", "exr", "npy"),
        help="also decode every .bdl file written (or up to date) beside it, in this format (after the "
        "batch, in this process); ktx2 and dds for normal maps",
    )
    p.add_argument("--mips", action="store_true", help="with --to: every level (see bandelets decode --mips)")
    p.add_argument("--gpu", choices=("bc5", "bc7", "rgba8"), help="with --to ktx2 or dds: the block format")
    add_green_option(p, decoding=True)


def write_outputs(data: bytes, output: str, level: int, mips: bool, gpu_format: str | None, green: str | None,
                  **options) -> tuple[np.ndarray, str, int]:  # fmt: skip
    """Decode the .bdl file ``data`` into ``output`` (a GPU file, an image or ``--mips`` images), as
    ``bandelets decode`` does (``options``: :func:`bandelets.decode`'s at level 0).

    Returns the image written first, what the GPU format adds (text for the summary line, or "")
    and the count of levels written."""
    from ..codec.decoder import decode
    from ..codec.levels import prefix_header
    from ..format.container import header_of
    from ..format.fields import Kind
    from ..io.files import write_array

    header = prefix_header(data) if level else header_of(data)
    gpu = gpu_suffix(output)
    if (gpu or green) and header.kind != Kind.NORMAL_MAP:
        raise ValueError("a .ktx2 or .dds output and --green are for normal maps")
    normal = header.kind == Kind.NORMAL_MAP
    levels = decoded_levels(data, level, mips and not gpu and not normal, decode, **options)
    if mips and not gpu and normal:
        from ..io.gpu import mip_chain

        levels = mip_chain(levels[0])
    levels = [flip_green(x, header.green, green) for x in levels]
    if gpu:
        from ..io.gpu import export

        # BC5 for a map coded as two channels (x, y or equidistant coordinates), BC7 for three.
        done = export(output, levels[0], gpu_format or ("bc5" if header.channels == 2 else None), mips=mips)
        added = f", {done.fmt.upper()} adds {done.error.mean:.3f} deg mean angle ({done.error.p99:.3f} p99)"
        return levels[0], added, len(done.sizes)
    if mips:
        for k, image in enumerate(levels):
            write_array(mip_name(output, k), image, header.kind, header.depth)
    else:
        write_array(output, levels[0], header.kind, header.depth)
    return levels[0], "", len(levels)


def ship(bdl: str, to: str, mips: bool, gpu_format: str | None, green: str | None) -> str:
    """Decode the .bdl file ``bdl`` beside it with the suffix ``to`` (``bandelets batch --to``); the path."""
    output = str(Path(bdl).with_suffix(f".{to}"))
    write_outputs(Path(bdl).read_bytes(), output, 0, mips, gpu_format, green)
    return output


def gpu_suffix(path: str) -> bool:
    """Whether ``path`` names a GPU file (.ktx2, .dds)."""
    return Path(path).suffix.lower() in GPU_SUFFIXES


def flip_green(decoded: np.ndarray, stored: str, wanted: str | None) -> np.ndarray:
    """``decoded`` in the ``wanted`` green convention (y negated, nothing else) when the file's
    ``stored`` one differs."""
    if wanted is None or wanted == stored:
        return decoded
    out = decoded.copy()
    out[..., 1] = -out[..., 1]
    return out


def decoded_levels(data: bytes, first: int, mips: bool, decode, **options) -> list[np.ndarray]:
    """The image at ``first``, and with ``mips`` every coarser level down to 1 x 1 (``decode``:
    :func:`bandelets.decode`, ``options`` its keywords at level 0)."""
    out = [decode(data, **options) if first == 0 else decode(data, level=first)]
    level = first
    while mips and max(out[-1].shape[:2]) > 1:
        level += 1
        out.append(decode(data, level=level))
    return out


def mip_name(output: str, k: int) -> str:
    """``OUT-k.suffix`` of ``OUT.suffix``."""
    path = Path(output)
    return str(path.with_name(f"{path.stem}-{k}{path.suffix}"))


def with_green(data: bytes, green: str) -> bytes:
    """The .bdl file ``data`` (tiled or not) labelled with the ``green`` convention (a header bit of
    format version 19, each tile's); its samples are unchanged."""
    from dataclasses import replace

    from ..codec.levels import _tile_bytes
    from ..format.container import is_tiled, pack, read
    from ..format.header import pack as pack_file
    from ..format.header import unpack

    if is_tiled(data):
        grid, _ = read(data)
        return pack(grid, [with_green(tile, green) for tile in _tile_bytes(data)])
    header, streams = unpack(data)
    return pack_file(replace(header, green=green), streams)
