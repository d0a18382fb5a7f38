"""How well a spherical parameterization samples a mesh, before any coding.

What ``bandelets geometry-image MESH --report`` prints: the stretch of the parameterization,
how unevenly the geometry image's samples cover the surface, and the uncoded geometry image's
Hausdorff PSNR and area against the original (the ceiling that no rate can pass).
"""

from __future__ import annotations

import numpy as np

from . import geometry_image, metrics

__all__ = ["parameterization_report"]


def parameterization_report(mesh, spherical, size: int) -> dict:
    """Quality of a parameterized mesh's ``size x size`` geometry image.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The original mesh.
    spherical : bandelets.surfaces.codec.SphericalMesh
        Its parameterization (:func:`bandelets.surfaces.codec.map_to_sphere`).
    size : int
        Side of the geometry image.

    Returns
    -------
    dict
        ``stretch``: L2 geometric stretch of the sphere map (1 at best, see
        :func:`.stretch.area_distortion`); ``sample_area_ratio``: largest over smallest surface
        area around a sample of the geometry image (a third of its triangles' areas);
        ``psnr``: Hausdorff PSNR (dB) of the uncoded geometry-image mesh against ``mesh``;
        ``area``: its area over ``mesh``'s.
    """
    positions = geometry_image.sample(spherical.vertices, spherical.faces, spherical.points, size)[0]
    remeshed = geometry_image.mesh_from_image(positions)
    around = np.bincount(
        remeshed.faces.ravel(), np.repeat(remeshed.area_faces / 3, 3), minlength=len(remeshed.vertices)
    )
    return {
        "stretch": float(spherical.distortion["stretch"]),
        "sample_area_ratio": float(around.max() / max(around.min(), 1e-300)),
        "psnr": metrics.hausdorff_psnr(mesh, remeshed),
        "area": float(remeshed.area / mesh.area),
    }
