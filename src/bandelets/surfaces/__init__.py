"""Surfaces: closed genus-0 meshes as spherical geometry images (the paper's section 6), any
other mesh as a multi-chart geometry image.

One module per stage, each plain functions on numpy arrays and ``trimesh.Trimesh`` objects:

========================  ===============================================================
:mod:`.checks`            closed, manifold, one component, genus 0 (or a clear error)
:mod:`.sphere`            flip-free spherical parameterization and its area distortion
:mod:`.octahedral`        sphere <-> octahedron <-> unit square, forward and inverse
:mod:`.geometry_image`    sampling positions and normals on the grid; the glued mesh back
:mod:`.metrics`           RMS symmetric Hausdorff distance (pymeshlab) and its PSNR
:mod:`.codec`             mesh -> .bdl -> mesh
:mod:`.charts`            any other topology: disk charts and their layout, from the faces alone
:mod:`.atlas`             the smoothest image through the vertices of that layout; reading it
:mod:`.chartcodec`        the multi-chart route: faces (Draco) + positions (geometry image)
:mod:`.parts`             several parts: closed genus-0 ones on the spherical path, one file
:mod:`.draco`             Google's Draco (DracoPy), the mesh anchor of ``bandelets rd``
:mod:`.meshlab`           every pymeshlab call in one thread of its own (safe in any thread)
========================  ===============================================================

This package imports trimesh, scipy, pymeshlab and fast-simplification; the rest of ``bandelets``
never imports it at start-up.
"""
