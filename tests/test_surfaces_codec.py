"""Geometry images, the glued mesh, Hausdorff PSNR, mesh coding and the mesh commands."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("pymeshlab")

from bandelets.apps.cli import main  # noqa: E402
from bandelets.format.header import unpack  # noqa: E402
from bandelets.surfaces import octahedral  # noqa: E402
from bandelets.surfaces.checks import check_genus0  # noqa: E402
from bandelets.surfaces.codec import (  # noqa: E402
    AUTO_SIZES,
    DEFAULT_SIZE,
    MIN_AUTO_BPP,
    auto_size,
    decode_mesh,
    encode_mesh,
    make_geometry_image,
    map_to_sphere,
)
from bandelets.surfaces.geometry_image import coarsen, mesh_from_image, triangulation  # noqa: E402
from bandelets.surfaces.metrics import hausdorff_psnr  # noqa: E402

KNIGHT = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes" / "decimated-knight.off"


@pytest.mark.parametrize("size", [4, 6, 32])
def test_triangulation_is_closed_genus0_and_faces_out(size):
    faces = triangulation(size)
    points = octahedral.square_to_sphere(octahedral.grid(size)).reshape(-1, 3)
    check_genus0(points, faces)
    q = points[faces]
    assert np.all(np.einsum("ij,ij->i", q[:, 0], np.cross(q[:, 1], q[:, 2])) > 0)


def test_odd_size_refused():
    with pytest.raises(ValueError, match="even side"):
        triangulation(33)


def test_coarsen_halves_the_octahedral_grid_while_it_keeps_enough_pixels():
    sphere = octahedral.square_to_sphere(octahedral.grid(32))
    coarse = coarsen(sphere, 64)  # 32 -> 16 -> 8 (64 pixels); 4 would have too few
    assert coarse.shape == (8, 8, 3)
    directions = coarse / np.linalg.norm(coarse, axis=2, keepdims=True)
    error = np.linalg.norm(directions - octahedral.square_to_sphere(octahedral.grid(8)), axis=2)
    assert np.max(error) < 0.06  # the pixels of side 8 are about 0.4 apart on the sphere
    assert coarsen(sphere, 257).shape == (32, 32, 3)


def test_sphere_geometry_image_lies_on_the_sphere():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    image = make_geometry_image(sphere, 32)
    radius = np.linalg.norm(image.positions, axis=2)
    assert radius.max() <= 1 + 1e-9 and radius.min() > 0.98
    assert np.allclose(np.linalg.norm(image.normals, axis=2), 1.0)
    # On a sphere the outward normal is the position direction.
    assert np.min(np.sum(image.normals * image.positions / radius[..., None], axis=2)) > 0.99


def test_psnr_of_a_known_displacement():
    sphere = trimesh.creation.icosphere(subdivisions=4)
    moved = sphere.copy()
    moved.vertices = moved.vertices * 1.01  # every point moves by 0.01 along the normal
    expected = 20 * np.log10(2 * np.sqrt(3) / 0.01)
    assert hausdorff_psnr(sphere, moved, samples=20_000) == pytest.approx(expected, abs=0.05)


def test_psnr_refuses_a_collapsed_mesh_instead_of_crashing():
    # As Draco leaves a long thin mesh at its coarsest quantization: every vertex in two points.
    # MeshLab's sampler dies with SIGSEGV on such a surface.
    sphere = trimesh.creation.icosphere(subdivisions=2)
    collapsed = sphere.copy()
    collapsed.vertices = np.where(sphere.vertices[:, :1] > 0, 1.0, -1.0) * [1.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="no area"):
        hausdorff_psnr(sphere, collapsed, samples=1000)


def test_encode_decode_mesh_is_closed_and_close():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    image = make_geometry_image(mesh, 32).positions
    data = encode_mesh(mesh, image=image, n_bytes=1500)
    assert len(data) <= 1500
    header, _ = unpack(data)  # the defaults: local frames, normal weight 2, spherical extension
    assert (header.frames, header.normal_weight, header.extension) == (True, 2.0, "spherical")
    decoded = decode_mesh(data, vertices="full")
    check_genus0(decoded.vertices, decoded.faces)
    assert decoded.is_watertight and decoded.volume > 0
    assert hausdorff_psnr(mesh_from_image(image), decoded, samples=20_000) > 35


def test_decoded_mesh_has_the_original_vertex_count_by_default():
    mesh = trimesh.creation.icosphere(subdivisions=3)  # 642 vertices, a 1024-vertex grid
    mesh.vertices *= (1.0, 0.7, 1.3)
    data = encode_mesh(mesh, size=32, bits_per_vertex=16)
    assert unpack(data)[0].mesh_vertices == len(mesh.vertices) == 642
    full = decode_mesh(data, vertices="full")
    assert len(full.vertices) == 32 * 32
    for asked, expected in ((None, 642), (200, 200), (5000, 32 * 32)):
        decoded = decode_mesh(data, vertices=asked)
        assert len(decoded.vertices) == expected and len(decoded.faces) == 2 * expected - 4
        check_genus0(decoded.vertices, decoded.faces)
        assert decoded.is_watertight and decoded.volume > 0  # closed, facing out
    # Quadric decimation to the original count costs little of the full grid's PSNR.
    psnr_full = hausdorff_psnr(mesh, full, samples=20_000)
    assert hausdorff_psnr(mesh, decode_mesh(data), samples=20_000) > psnr_full - 1.5
    # A geometry image made from no mesh holds no count: the whole grid.
    from bandelets import encode

    plain = encode(make_geometry_image(mesh, 32).positions, bpp=4.0, kind="geometry-image")
    assert len(decode_mesh(plain).vertices) == 32 * 32
    for bad in (3, "half", 2.5):
        with pytest.raises(ValueError, match="at least 4 vertices|vertices must be"):
            decode_mesh(data, vertices=bad)


def test_mesh_files_ask_for_no_restoration_unless_told():
    # Restoring the positions lowers their L2 error but the Hausdorff PSNR too (rd_meshes.py).
    mesh = trimesh.creation.icosphere(subdivisions=3)
    mesh.vertices *= (1.0, 0.7, 1.3)
    image = make_geometry_image(mesh, 32).positions
    plain = encode_mesh(mesh, image=image, n_bytes=600, frames=False)
    restored = encode_mesh(mesh, image=image, n_bytes=600, frames=False, restore=True)
    assert unpack(plain)[0].restoration == 0
    assert unpack(plain)[1] == unpack(restored)[1]  # the same coefficients either way


@pytest.mark.parametrize("bits", [0, 100, 1638, 1639, 6554, 50_000, 104_858, 1e9])
def test_auto_size_is_the_largest_side_with_enough_bits_per_pixel(bits):
    side = auto_size(bits)
    assert side in AUTO_SIZES
    assert side == AUTO_SIZES[0] or bits / side**2 >= MIN_AUTO_BPP
    larger = [n for n in AUTO_SIZES if n > side]
    assert not larger or bits / larger[0] ** 2 < MIN_AUTO_BPP


def test_encode_mesh_sizes_the_image_by_its_target():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    spherical = map_to_sphere(mesh)
    chosen = encode_mesh(mesh, n_bytes=300, spherical=spherical)
    assert len(chosen) <= 300 and unpack(chosen)[0].width == auto_size(2400) == 128
    assert unpack(encode_mesh(mesh, n_bytes=300, size=32, spherical=spherical))[0].width == 32
    per_pixel = encode_mesh(mesh, bpp=0.05, spherical=spherical)
    assert unpack(per_pixel)[0].width == DEFAULT_SIZE and len(per_pixel) <= 0.05 * DEFAULT_SIZE**2 / 8
    with pytest.raises(ValueError, match="size 64 given with a 32 x 32 geometry image"):
        encode_mesh(mesh, size=64, image=make_geometry_image(mesh, 32).positions)


def test_decode_mesh_refuses_other_kinds():
    from bandelets import encode

    data = encode(np.random.default_rng(0).random((16, 16)), bpp=4.0)
    with pytest.raises(ValueError, match="not a mesh file"):
        decode_mesh(data)


def test_mesh_commands(tmp_path, capsys):
    if not KNIGHT.is_file():
        pytest.skip(f"{KNIGHT} is absent: the real test meshes live beside the project, not in it")
    bdl, obj = tmp_path / "k.bdl", tmp_path / "k.obj"
    options = ["--no-frames", "--extension", "symmetric"]
    assert (
        main(["mesh-encode", str(KNIGHT), str(bdl), "--size", "32", "--bits-per-vertex", "16", *options]) == 0
    )
    assert bdl.stat().st_size <= 16 * 502 / 8
    capsys.readouterr()
    assert main(["info", str(bdl)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["frames"], info["normal_weight"], info["extension"]) == (False, 1.0, "symmetric")
    assert info["mesh_vertices"] == 502
    for extra, count in (([], 502), (["--full"], 32 * 32), (["--vertices", "300"], 300)):
        assert main(["mesh-decode", str(bdl), str(obj), "-f", *extra]) == 0
        decoded = trimesh.load(obj, force="mesh", process=False)
        assert len(decoded.vertices) == count and decoded.is_watertight
    assert main(["mesh-decode", str(bdl), str(obj), "-f", "--vertices", "2"]) == 2
    assert "--vertices must be at least 4" in capsys.readouterr().err
    gi, normals = tmp_path / "g.npy", tmp_path / "n.png"
    assert main(["geometry-image", str(KNIGHT), str(gi), "--size", "16", "--normals", str(normals)]) == 0
    assert np.load(gi).shape == (16, 16, 3) and normals.stat().st_size > 0


def test_mesh_encode_restores_only_when_asked(tmp_path, capsys):
    if not KNIGHT.is_file():
        pytest.skip(f"{KNIGHT} is absent: the real test meshes live beside the project, not in it")
    counts = []
    for extra in ([], ["--restore"]):
        bdl = tmp_path / f"k{len(extra)}.bdl"
        assert (
            main(["mesh-encode", str(KNIGHT), str(bdl), "--size", "32", "--bits-per-vertex", "16", *extra])
            == 0
        )
        capsys.readouterr()
        assert main(["info", str(bdl)]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["frames"]
        counts.append(info["restoration"])
    assert counts[0] == 0 < counts[1]


def test_mesh_command_errors(tmp_path, capsys):
    triangle = tmp_path / "triangle.off"
    triangle.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert main(["mesh-encode", str(triangle), str(tmp_path / "t.bdl")]) == 2
    assert f"bandelets: error: {triangle}: the mesh is a single triangle" in capsys.readouterr().err
    assert not (tmp_path / "t.bdl").exists()
    torus = tmp_path / "torus.off"  # any genus is taken (the chart route): the options are still checked
    torus.write_bytes(trimesh.creation.torus(1.0, 0.3).export(file_type="off").encode())
    assert main(["mesh-encode", str(torus), str(tmp_path / "t.bdl"), "--normal-weight", "100"]) == 2
    assert "normal_weight must be from 1/64 to 64" in capsys.readouterr().err
    assert main(["mesh-decode", str(tmp_path / "missing.bdl"), str(tmp_path / "x.stl")]) == 2
    assert main(["geometry-image", str(torus), str(tmp_path / "t.png")]) == 2
    assert "unsupported output format" in capsys.readouterr().err


def test_coarsen_bounds_the_pixels_whatever_the_vertex_count():
    sphere = octahedral.square_to_sphere(octahedral.grid(32))
    assert coarsen(sphere, 1000, most=256).shape == (16, 16, 3)  # 1000 alone would keep 32
    assert coarsen(sphere, 10, most=256).shape == (4, 4, 3)  # the vertex count rules when fewer
    assert coarsen(sphere[:12, :12], 1, most=4).shape == (6, 6, 3)  # no odd side


def _prints_and_exits_cleanly(code: str, printed: str) -> None:
    """``code`` run in a Python process of its own prints ``printed`` and exits with status 0 (a
    fault of the heap aborts the process at exit, after the output)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert (done.returncode, done.stdout) == (0, printed), done.stderr[-500:]


def test_decode_mesh_in_a_thread_leaves_the_heap_sound():
    # pymeshlab run from a thread that ends before the exit handlers aborted the process at exit
    # (bandelets.surfaces.meshlab): decode in a thread, in a process of its own.
    code = (
        "import threading, trimesh\n"
        "from bandelets.surfaces.codec import encode_mesh, decode_mesh\n"
        "data = encode_mesh(trimesh.creation.icosphere(subdivisions=2), bits_per_vertex=16)\n"
        "out = []\n"
        "thread = threading.Thread(target=lambda: out.append(decode_mesh(data)))\n"
        "thread.start(); thread.join()\n"
        "print(len(out[0].vertices))\n"
    )
    _prints_and_exits_cleanly(code, "162\n")


def test_pymeshlab_thread_outlives_the_exit_handlers():
    # pymeshlab's plugins belong to the thread that imported it; MeshLab's PluginManager,
    # destroyed by the C++ exit handlers, decremented a freed QThreadData when that thread had
    # ended (a ThreadPoolExecutor's worker is joined at shutdown), and glibc aborted
    # ("malloc_consolidate(): unaligned fastbin chunk detected"): always when numba's compiler
    # had run in that thread first (bandelets.surfaces.meshlab).
    code = (
        "import numpy as np\n"
        "from numba import njit\n"
        "from bandelets.surfaces.meshlab import confined\n"
        "total = njit(lambda a: a.sum())\n"
        "@confined\n"
        "def load():\n"
        "    total(np.ones(3))\n"
        "    import pymeshlab\n"
        "    return pymeshlab.MeshSet().mesh_number()\n"
        "print(load())\n"
    )
    _prints_and_exits_cleanly(code, "0\n")
