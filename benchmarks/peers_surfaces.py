"""TetGen for ``peers.py``: a surface triangulation of each analytic shape, independent of bitemesh, then
``tetrahedralize`` with ``-pq1.2a<maxvolume>``.

Sphere: a geodesic icosphere; torus: a (u, v) grid.  Die and two-cavity heart: gmsh's 2D mesh (uniform size h) of
the exact CAD of ``peers_cad``.  Marching cubes of the analytic f was tried first: at an edge of h it cannot follow
the heart's 0.10 RV wall (one edge thick at 10,000 tets), and decimating a finer one (vtkQuadricDecimation) left
edges of CV 0.8 and triangles of quality 0.02, a handicap to TetGen that its peers do not have.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

def icosphere(frequency: int):
    """Geodesic unit sphere: each icosahedron face split into frequency^2 triangles, projected on the sphere."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    n = frequency
    points, faces = [], []
    for a, b, c in f:
        ids = {}
        for i in range(n + 1):
            for j in range(n + 1 - i):
                ids[i, j] = len(points)
                points.append(v[a] + (v[b] - v[a]) * i / n + (v[c] - v[a]) * j / n)
        for i in range(n):
            for j in range(n - i):
                faces.append([ids[i, j], ids[i + 1, j], ids[i, j + 1]])
                if j < n - i - 1:
                    faces.append([ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]])
    points = np.array(points)
    points /= np.linalg.norm(points, axis=1)[:, None]
    keys = np.round(points, 9)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return points[first], inverse.reshape(-1)[np.array(faces)]


def torus_surface(nu: int, nv: int, major=1.0, minor=0.4):
    """Closed (u, v) grid triangulation of the torus, outward-oriented."""
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, V = np.meshgrid(u, v, indexing="ij")
    points = np.stack([(major + minor * np.cos(V)) * np.cos(U), (major + minor * np.cos(V)) * np.sin(U),
                       minor * np.sin(V)], axis=-1).reshape(-1, 3)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij"))
    idx = lambda a, b: (a % nu) * nv + (b % nv)  # noqa: E731
    faces = np.concatenate([np.stack([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)], axis=1),
                            np.stack([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)], axis=1)])
    return points, faces


def edges_of(faces) -> np.ndarray:
    """(e, 2) sorted edges of a triangulation, with multiplicity (one row per face side)."""
    return np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)


def check_closed(faces, euler: int, what: str) -> None:
    """Raise unless every edge has two faces and V - E + F = euler."""
    edges, count = np.unique(edges_of(faces), axis=0, return_counts=True)
    vertices = np.unique(faces).size
    if np.any(count != 2) or vertices - len(edges) + len(faces) != euler:
        raise RuntimeError(f"{what}: the surface is not closed and manifold with Euler characteristic {euler} "
                           f"({np.count_nonzero(count != 2)} bad edges, V - E + F = "
                           f"{vertices - len(edges) + len(faces)})")


def surface(name: str, shape, h: float):
    """The surface triangulation of shape ``name`` at edge length about h: (points, faces, how it was made)."""
    if name == "sphere":
        frequency = max(2, round(1.05 / h))  # the icosahedron's edge on the unit sphere is ~1.05
        points, faces = icosphere(frequency)
        how = f"an icosphere (frequency {frequency})"
    elif name == "torus":
        points, faces = torus_surface(max(8, round(2 * np.pi * 1.0 / h)), max(6, round(2 * np.pi * 0.4 / h)))
        how = "a (u, v) grid"
    else:
        from peers_cad import gmsh_surface
        points, faces = gmsh_surface(name, h)
        how = "gmsh's 2D mesh of the CAD"
    check_closed(faces, shape.boundary_euler, f"the TetGen surface of {name} at h = {h:.4g}")
    return points, faces, how


def tetgen_once(points, faces, maxvolume: float):
    """TetGen -pq1.2a<maxvolume> of a closed triangulation: (nodes (n, 3), tets (m, 4), seconds)."""
    import tetgen
    tet = tetgen.TetGen(points, faces.astype(np.int32))
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:  # the wrapper prints "parsing switches" on the C stdout
        os.dup2(null.fileno(), 1)
        try:
            start = time.perf_counter()
            nodes, elems, *_ = tet.tetrahedralize(switches=f"pq1.2a{maxvolume:.6g}Q")
            seconds = time.perf_counter() - start
        finally:
            os.dup2(saved, 1)
            os.close(saved)
    return nodes, elems[:, :4], seconds
