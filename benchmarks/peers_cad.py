"""gmsh for ``peers.py``: the exact CAD (OpenCASCADE) of each analytic shape of ``bitemesh.core.shapes``, meshed with
gmsh's Delaunay and Netgen optimisation on one thread.

The solids follow the shapes' definitions: the die is a box of half-side 1 with its 12 edges filleted (radius 0.25,
so the corners are sphere octants, as the rounded cube of ``shapes.die``) minus 21 balls of radius 0.16 centred on
the faces; the two-cavity heart is (LV outer U RV outer) minus the LV cavity minus (RV cavity minus LV outer), cut
by the plane z = 0.40, each ellipsoid a unit ball dilated by its semi-axes.  OCC's volume (``occ.getMass``) of
the solid agrees with ``Shape.measure`` (exact for the sphere, torus and die; the heart's 1.01537 against the
quasi-Monte Carlo 1.01852 is OCC's approximate integration over the BSpline ellipsoids: each dilated ball's nodes
lie on its ellipsoid to 1e-15, its getMass is 0.04 % low).
"""
from __future__ import annotations

import time

import numpy as np
from bitemesh.core.shapes import HEART_BASE, HEART_ELLIPSOIDS, die_pip_centres


def _ellipsoid(occ, centre, semi_axes) -> int:
    tag = occ.addSphere(0, 0, 0, 1.0)
    occ.dilate([(3, tag)], 0, 0, 0, *semi_axes)
    occ.translate([(3, tag)], *centre)
    return tag


def build(name: str) -> None:
    """Add the OCC solid of shape ``name`` (peers' names) to the current gmsh model and synchronize."""
    import gmsh
    occ = gmsh.model.occ
    if name == "sphere":
        occ.addSphere(0, 0, 0, 1.0)
    elif name == "torus":
        occ.addTorus(0, 0, 0, 1.0, 0.4)
    elif name == "die":
        box = occ.addBox(-1, -1, -1, 2, 2, 2)
        occ.synchronize()
        edges = [tag for _, tag in gmsh.model.getEntities(1)]  # the box's 12 edges (the model holds only the box)
        rounded = occ.fillet([box], edges, [0.25])
        pips = [(3, occ.addSphere(*c, 0.16)) for c in die_pip_centres()]
        occ.cut(rounded, pips)
    elif name == "two-cavity-heart":
        lv_outer, lv_inner, rv_outer, rv_inner = (_ellipsoid(occ, *HEART_ELLIPSOIDS[k])
                                                  for k in ("lv_outer", "lv_inner", "rv_outer", "rv_inner"))
        keep = _ellipsoid(occ, *HEART_ELLIPSOIDS["lv_outer"])  # a copy: the RV cavity is cut by the LV outer ellipsoid
        rv_cavity, _ = occ.cut([(3, rv_inner)], [(3, keep)])
        walls, _ = occ.fuse([(3, lv_outer)], [(3, rv_outer)])
        solid, _ = occ.cut(walls, [(3, lv_inner)] + rv_cavity)
        above = occ.addBox(-2, -2, HEART_BASE, 4, 4, 2)
        occ.cut(solid, [(3, above)])
    else:
        raise ValueError(f"peers_cad.build: no CAD for shape {name!r}")
    occ.synchronize()


def gmsh_once(name: str, h: float):
    """One gmsh run at uniform size h: (nodes (n, 3), tets (m, 4) int64, wall and CPU seconds of generate(3))."""
    import gmsh
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(name)
        build(name)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay (the default)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.option.setNumber("Mesh.OptimizeNetgen", 1)
        start, cpu = time.perf_counter(), time.process_time()
        gmsh.model.mesh.generate(3)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, node_tags = gmsh.model.mesh.getElementsByType(4)
    finally:
        gmsh.finalize()
    index = np.full(int(tags.max()) + 1, -1, np.int64)
    index[tags.astype(np.int64)] = np.arange(tags.size)
    return coords.reshape(-1, 3), index[node_tags.astype(np.int64).reshape(-1, 4)], seconds, cpu


def gmsh_surface(name: str, h: float):
    """gmsh's triangulation (uniform size h) of the CAD's boundary: (points (n, 3) float64, faces (m, 3) int64)."""
    import gmsh
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        build(name)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, node_tags = gmsh.model.mesh.getElementsByType(2)
    finally:
        gmsh.finalize()
    faces = node_tags.astype(np.int64).reshape(-1, 3)
    used = np.unique(faces)
    index = np.full(int(tags.max()) + 1, -1, np.int64)
    index[tags.astype(np.int64)] = np.arange(tags.size)
    points = coords.reshape(-1, 3)[index[used]]
    renumber = np.full(int(tags.max()) + 1, -1, np.int64)
    renumber[used] = np.arange(used.size)
    return np.ascontiguousarray(points, dtype=np.float64), renumber[faces]
