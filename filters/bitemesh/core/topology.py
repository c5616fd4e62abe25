"""Combinatorics of simplicial meshes: facets, boundary, components and the manifold tests, vectorized.

Names follow the dimension k of the cells: a *facet* has k vertices (a triangle of a tetrahedron, an edge of a
triangle), a *ridge* has k - 1 (an edge of a tetrahedron, a vertex of a triangle).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from .mesh import facets_of


def unique_rows(rows: np.ndarray):
    """Group rows of vertex indices that hold the same vertices, whatever their order.

    Returns
    -------
    unique : (u, j) int64, each distinct row once, sorted
    inverse : (r,) int64, the group of each input row
    counts : (u,) int64, the size of each group
    """
    rows = np.sort(rows.reshape(-1, rows.shape[-1]), axis=1).astype(np.int64, copy=False)
    n_points = int(rows.max()) + 1 if rows.size else 1
    if float(n_points) ** rows.shape[1] < 2.0**63:  # an exact int64 key per sorted row: much faster than axis=0
        keys = rows[:, 0].copy()
        for column in range(1, rows.shape[1]):
            keys = keys * n_points + rows[:, column]
        _, first, inverse, counts = np.unique(keys, return_index=True, return_inverse=True, return_counts=True)
        return rows[first], inverse.ravel(), counts
    unique, inverse, counts = np.unique(rows, axis=0, return_inverse=True, return_counts=True)
    return unique, inverse.ravel(), counts


def facet_table(cells: np.ndarray):
    """Every facet of every cell, and which of them are the same facet.

    Returns
    -------
    facets : (m (k + 1), k) int64, facet i of cell c at row c (k + 1) + i, oriented out of its cell
    inverse : (m (k + 1),) int64, the same number for the rows that are the same facet
    counts : (u,) int64, how many cells hold each distinct facet (1 on the boundary, 2 inside)
    """
    facets = facets_of(cells).reshape(-1, cells.shape[1] - 1)
    _, inverse, counts = unique_rows(facets)
    return facets, inverse, counts


def neighbour_pairs(inverse: np.ndarray):
    """(a, b): the row pairs of a facet table that are the same facet, as indices into the table."""
    order = np.argsort(inverse, kind="stable")
    same = inverse[order[1:]] == inverse[order[:-1]]
    return order[:-1][same], order[1:][same]


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """(b, k) the facets held by one cell only, in cell order, oriented out of the domain.

    3D: triangles (p, q, r) with (q - p) x (r - p) pointing out.  2D: edges (p, q) with the domain on the left.
    """
    facets, inverse, counts = facet_table(cells)
    return facets[counts[inverse] == 1]


def connected_components(cells: np.ndarray) -> np.ndarray:
    """(m,) labels 0 .. c - 1 of the cells joined through shared facets (not through edges or vertices only)."""
    if len(cells) == 0:
        return np.zeros(0, np.int64)
    _, inverse, _ = facet_table(cells)
    a, b = neighbour_pairs(inverse)
    per_cell = cells.shape[1]
    graph = sparse.coo_matrix((np.ones(len(a)), (a // per_cell, b // per_cell)), shape=(len(cells),) * 2)
    return csgraph.connected_components(graph, directed=False)[1].astype(np.int64)


def faces_of(simplices: np.ndarray, size: int) -> np.ndarray:
    """(m, C(j, size), size) the faces with ``size`` vertices of each of the (m, j) simplices."""
    return np.stack([simplices[:, list(c)] for c in combinations(range(simplices.shape[1]), size)], axis=1)


def distinct_faces(simplices: np.ndarray, size: int) -> np.ndarray:
    """(u, size) int64, each distinct face with ``size`` vertices of ``simplices`` once, vertices sorted."""
    return unique_rows(faces_of(simplices, size).reshape(-1, size))[0]


def euler_characteristic(simplices: np.ndarray) -> int:
    """Euler characteristic (vertices - edges + triangles - ...) of the complex that ``simplices`` (m, k + 1) span."""
    return sum((-1) ** (size - 1) * len(distinct_faces(simplices, size)) for size in range(1, simplices.shape[1] + 1))


def count_faces(simplices: np.ndarray, size: int, n_points: int) -> np.ndarray:
    """(n_points,) how many distinct faces with ``size`` vertices of ``simplices`` hold each point."""
    return np.bincount(distinct_faces(simplices, size).ravel(), minlength=n_points)


def pinched_ridges(cells: np.ndarray) -> np.ndarray:
    """(r, k - 1) the ridges around which the cells form two or more separate fans (a non-manifold boundary).

    Around a ridge the cells that hold it are linked through the interior facets that hold it: a closed ring (#cells
    = #facets) or a single open fan (#cells = #facets + 1) is manifold.
    """
    k = cells.shape[1] - 1
    facets, inverse, _ = facet_table(cells)
    interior = facets[neighbour_pairs(inverse)[0]]
    cell_ridges = faces_of(cells, k - 1).reshape(-1, k - 1)
    facet_ridges = faces_of(interior, k - 1).reshape(-1, k - 1)
    ridges, groups, _ = unique_rows(np.concatenate([cell_ridges, facet_ridges]))
    around = np.bincount(groups[:len(cell_ridges)], minlength=len(ridges))
    linked = np.bincount(groups[len(cell_ridges):], minlength=len(ridges))
    return ridges[around - linked >= 2]


def pinched_vertices(cells: np.ndarray, n_points: int) -> np.ndarray:
    """(v, 1) the vertices whose link is not a sphere (inside) or a disk (on the boundary).

    The link's Euler characteristic is sum over d = 1..k of (-1)^(d-1) (number of d-simplices holding the vertex);
    it must be 1 + (-1)^(k-1) for an interior vertex and 1 for a boundary vertex.
    """
    k = cells.shape[1] - 1
    euler = sum((-1) ** (d - 1) * count_faces(cells, d + 1, n_points) for d in range(1, k + 1))
    on_boundary = np.zeros(n_points, bool)
    on_boundary[boundary_facets(cells).ravel()] = True
    used = np.zeros(n_points, bool)
    used[cells.ravel()] = True
    expected = np.where(on_boundary, 1, 1 + (-1) ** (k - 1))
    return np.flatnonzero(used & (euler != expected))[:, None]


def non_manifold_faces(cells: np.ndarray, n_points: int) -> list:
    """The faces (arrays of (b, size) vertex ids) at which the domain is not a manifold with boundary."""
    found = [pinched_ridges(cells)]
    if cells.shape[1] > 3:
        found.append(pinched_vertices(cells, n_points))
    return [faces for faces in found if len(faces)]


def vertex_incidence(n_points: int, cells: np.ndarray) -> sparse.csr_matrix:
    """(n_points, m) sparse, 1 where a point is a vertex of a cell."""
    return sparse.csr_matrix((np.ones(cells.size), (cells.ravel(), np.repeat(np.arange(len(cells)), cells.shape[1]))),
                             shape=(n_points, len(cells)))


def euler_change(incidence: sparse.csr_matrix, cells: np.ndarray, keep: np.ndarray, changed: np.ndarray,
                 value: bool) -> int:
    """How much setting ``keep[changed] = value`` changes the Euler characteristic of the kept complex.

    Only faces of the changed cells come or go, so the cells around their vertices suffice.  -1: a tunnel opens
    (or two parts join twice); +1: a loop breaks (or a void closes).
    """
    near = np.flatnonzero(incidence[np.unique(cells[changed])].sum(axis=0).A1 > 0)
    after = keep[near].copy()
    after[np.isin(near, changed)] = value
    return euler_characteristic(cells[near[after]]) - euler_characteristic(cells[near[keep[near]]])
