"""The one line ``mesh-encode`` prints on stderr when it succeeds, and ``info`` of a chart mesh record."""

from __future__ import annotations

__all__ = ["mesh_encode_summary", "representation"]


def representation(data: bytes) -> dict:
    """Which representation a mesh file holds: ``"spherical geometry image"`` (a plain .bdl
    geometry image), ``"multi-chart geometry image"`` or ``"draco"`` (a chart mesh record, see
    :func:`bandelets.surfaces.chartcodec.describe`), or ``"parts"`` (a record of parts,
    :mod:`bandelets.surfaces.parts`, with each part's representation)."""
    from ..surfaces import chartcodec, parts

    if chartcodec.is_chart_file(data):
        return chartcodec.describe(data)
    if parts.is_parts_file(data):  # the vertices and faces the decoded mesh has
        inner = [representation(f) for f in parts.files(data)]
        counts = {key: sum(part[key] for part in inner) for key in ("vertices", "faces")}
        return {"representation": "parts", "bytes": len(data)} | counts | {"parts": inner}
    from ..format.container import header_of

    header = header_of(data)
    vertices = header.mesh_vertices or header.width**2  # the decoder's default count
    return {
        "representation": "spherical geometry image",
        "side": header.width,
        "bytes": len(data),
        "vertices": vertices,
        "faces": 2 * vertices - 4,
    }


def mesh_encode_summary(source: str, output: str, mesh, data: bytes, seconds: float) -> str:
    """``"in.obj -> out.bdl: 4494 vertices, 8988 faces -> 4973 bytes (8.85 bits per vertex),
    multi-chart geometry image 84 x 84 and a normal layer of 883 bytes, 16.7 s"``, and what was
    split into manifold pieces."""
    import numpy as np

    from ..surfaces import chartcodec

    about = representation(data)
    kind = about["representation"]
    if kind == "draco":
        how = "Draco's own stream (no geometry image was better at this size)"
    elif kind == "parts":
        how = f"{len(about['parts'])} parts: " + ", ".join(
            f"{part['representation']} {part.get('side', '')}".strip() for part in about["parts"]
        )
    else:
        how = f"{kind} {about['side']} x {about['side']}"
        if about.get("normal_layer_bytes"):
            how += f" and a normal layer of {about['normal_layer_bytes']} bytes"
    split = ""
    if kind != "spherical geometry image":
        split = chartcodec.check_surface(np.asarray(mesh.vertices), np.asarray(mesh.faces))[2].summary()
    n = len(mesh.vertices)
    return (
        f"{source} -> {output}: {n} vertices, {len(mesh.faces)} faces -> {len(data)} bytes "
        f"({8 * len(data) / n:.2f} bits per vertex), {how}, {seconds:.1f} s" + (f"; {split}" if split else "")
    )
