"""How the chart route lays out a mesh, before any coding (``geometry-image --report``)."""

from __future__ import annotations

import numpy as np

from . import atlas, charts
from .chartcodec import chart_side, check_surface, fitting_side

__all__ = ["chart_report"]


def _stretch(pixels: np.ndarray, corners: np.ndarray, positions: np.ndarray) -> float:
    """L2 geometric stretch of the layout (Sander et al.), normalized to 1 at best: the RMS over
    the surface of the map's singular values, over that of a map preserving the total area.
    Triangles flat in the layout (three vertices on one side of a square) are left out."""
    uv = pixels[corners]  # (F, 3, 2)
    xyz = positions  # (F, 3, 3)
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area_uv = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    keep = np.abs(area_uv) > 1e-6 * np.median(np.abs(area_uv))
    q1, q2 = xyz[keep, 1] - xyz[keep, 0], xyz[keep, 2] - xyz[keep, 0]
    a = 2.0 * area_uv[keep]
    # Partial derivatives of the positions along the layout's two axes.
    ds = (q1 * d2[keep, 1:2] - q2 * d1[keep, 1:2]) / a[:, None]
    dt = (q2 * d1[keep, 0:1] - q1 * d2[keep, 0:1]) / a[:, None]
    area_3d = 0.5 * np.linalg.norm(np.cross(q1, q2), axis=1)
    mean_square = np.sum(area_3d * 0.5 * (np.sum(ds**2, 1) + np.sum(dt**2, 1))) / np.sum(area_3d)
    return float(np.sqrt(mean_square * np.sum(np.abs(area_uv[keep])) / np.sum(area_3d)))


def chart_report(mesh, size: int | None = None) -> dict:
    """How the chart route lays out a mesh, before any coding (``geometry-image --report``).

    Returns
    -------
    dict
        ``charts``: their count; ``side``: of the image; ``used``: share of the image inside the
        charts' squares; ``stretch``: :func:`_stretch` (1 at best; Tutte's uniform weights squeeze
        the triangles along the squares' sides, which this mean weighs heavily);
        ``seam_copies``: extra copies of the vertices on the seams, over the vertex count;
        ``psnr``: Hausdorff PSNR (dB) against ``mesh`` of the mesh read back from the uncoded
        image (the ceiling no rate passes); ``image``: the image, shape (side, side, 3).
    """
    import trimesh

    from . import metrics

    vertices, faces, _ = check_surface(mesh.vertices, mesh.faces)
    labels = charts.region_charts(faces)
    side = fitting_side(labels, faces, chart_side(len(vertices))) if size is None else int(size)
    layout = charts.layout(faces, labels, side)
    owned = charts.owners(layout)
    image = atlas.fit(layout.pixels[owned], vertices[layout.corner_vertex[owned]], side)
    back = np.zeros_like(vertices)
    back[layout.corner_vertex[owned]] = atlas.sample(image, layout.pixels[owned])
    sizes = charts.pack(np.bincount(layout.corner_chart), side)[1]
    return {
        "charts": int(labels.max()) + 1,
        "side": side,
        "used": float(np.sum(sizes.astype(np.float64) ** 2) / side**2),
        "stretch": _stretch(layout.pixels, layout.face_corners, vertices[faces]),
        "seam_copies": float(len(owned) / len(vertices) - 1.0),
        "psnr": metrics.hausdorff_psnr(mesh, trimesh.Trimesh(back, faces, process=False)),
        "image": image,
    }
