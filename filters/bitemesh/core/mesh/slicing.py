"""A k-D simplicial mesh cut by the hyperplane x_axis = value: the (k-1)-D simplicial mesh of the section (an
instant of a space-time mesh, a 3-D section of a 4-D domain).

A cell with a vertices on one side and b on the other (a + b = k + 1) meets the hyperplane in the product of two
simplices, Delta^(a-1) x Delta^(b-1), whose vertices are the a b points where its crossing edges meet the plane.
That polytope is cut into C(a + b - 2, a - 1) simplices by the staircase rule: each simplex is a monotone path
through the a x b grid of crossing edges, the vertices of each side taken in the order of their indices.  Two cells
that share a face order its vertices alike, so the pieces meet face to face: the section is a conforming mesh.
"""
from __future__ import annotations

from functools import cache
from itertools import combinations

import numpy as np

from ..errors import InvalidInputError, check_number
from .simplicial import Mesh, signed_measures

#: a node nearer the plane than this share of the mesh's extent along the axis lies on it (a cut 1e-12 beside a node
#: left slivers of 1e-14 volume).
ON_PLANE = 1e-9


@cache
def staircase(above: int, below: int) -> np.ndarray:
    """(C(above + below - 2, above - 1), above + below - 1, 2) int: the simplices of Delta^(above-1) x
    Delta^(below-1), each as its vertices (i, j), i an index among the vertices above, j among those below."""
    steps = above + below - 2
    paths = []
    for rises in combinations(range(steps), above - 1):
        i = j = 0
        path = [(0, 0)]
        for step in range(steps):
            i, j = (i + 1, j) if step in rises else (i, j + 1)
            path.append((i, j))
        paths.append(path)
    return np.array(paths, dtype=np.int64).reshape(len(paths), steps + 1, 2)


def slice_mesh(mesh: Mesh, value: float, axis: int = -1) -> Mesh:
    """The section of ``mesh`` (points (n, k), cells (m, k + 1), k >= 3) by the hyperplane x_axis = ``value``: a
    (k-1)-D mesh whose points are those of the section with the coordinate ``axis`` left out, its cells positively
    oriented.  A node on the plane (within :data:`ON_PLANE`) is a node of the section, the pieces it flattens left
    out.  Empty
    (no cell) where the plane misses the mesh."""
    points, cells = np.asarray(mesh.points, np.float64), np.asarray(mesh.cells, np.int64)
    k = points.shape[1]
    if k < 3:
        raise InvalidInputError(f"slice_mesh cuts a mesh of 3 or more dimensions, got {k}-D points")
    axis = int(axis) % k
    value = check_number(value, "value")
    reach = float(np.ptp(points[:, axis])) if len(points) else 0.0
    near = np.abs(points[:, axis] - value) <= ON_PLANE * reach   # on the plane, to rounding
    side = (points[:, axis] >= value) | near
    count = side[cells].sum(axis=1)
    kept = [axis_ for axis_ in range(k) if axis_ != axis]
    pieces = []
    for above in range(1, k + 1):
        crossing = cells[count == above]
        if not len(crossing):
            continue
        up = side[crossing]
        order = np.argsort(~up, axis=1, kind="stable")   # the vertices above first, then those below
        ranked = np.take_along_axis(crossing, order, axis=1)
        upper = np.sort(ranked[:, :above], axis=1)
        lower = np.sort(ranked[:, above:], axis=1)
        path = staircase(above, k + 1 - above)                                   # (s, k, 2)
        pieces.append(np.stack([upper[:, path[..., 0]], lower[:, path[..., 1]]], axis=-1).reshape(-1, k, 2))
    if not pieces:
        return Mesh(np.zeros((0, k - 1)), np.zeros((0, k), np.int64))
    edges = np.concatenate(pieces)                                               # (c, k, 2): each vertex an edge
    on_plane = near[edges[..., 0]]
    edges[on_plane, 1] = edges[on_plane, 0]   # a node on the plane: every edge from it meets the plane there
    unique, inverse = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True)
    start, end = points[unique[:, 0]], points[unique[:, 1]]
    span = start[:, axis] - end[:, axis]
    t = np.divide(start[:, axis] - value, span, out=np.zeros(len(span)), where=span != 0)
    section = (start + t[:, None] * (end - start))[:, kept]
    simplices = inverse.reshape(-1, k)
    sorted_ = np.sort(simplices, axis=1)
    simplices = simplices[(sorted_[:, 1:] != sorted_[:, :-1]).all(axis=1)]   # pieces flattened onto such a node
    flipped = signed_measures(section, simplices) < 0
    simplices[flipped, :2] = simplices[flipped, 1::-1]
    return Mesh(section, simplices)
