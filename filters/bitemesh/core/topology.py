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


def unique_rows(simplices: np.ndarray):
    """Identify simplices up to vertex order.

    Returns
    -------
    unique : (u, j) int64, each distinct simplex once, vertices sorted
    inverse : (s,) int64, row of ``unique`` for each input simplex
    counts : (u,) int64, how many input simplices are each unique one
    """
    keys = np.sort(simplices.reshape(len(simplices), -1), axis=1)
    if len(keys) == 0:
        return keys, np.zeros(0, np.int64), np.zeros(0, np.int64)
    unique, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    return unique, inverse.ravel(), counts


def facet_table(cells: np.ndarray):
    """Facets of ``cells`` (m, k + 1): ``facet_ids`` (m, k + 1) into ``unique`` (u, k) and ``counts`` (u,)."""
    unique, inverse, counts = unique_rows(facets_of(cells).reshape(-1, cells.shape[1] - 1))
    return inverse.reshape(len(cells), cells.shape[1]), unique, counts


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """(b, k) the facets that belong to one cell only, ordered with their normal pointing out of the domain."""
    facet_ids, _, counts = facet_table(cells)
    return facets_of(cells)[counts[facet_ids] == 1]


def cell_graph(cells: np.ndarray) -> sparse.csr_matrix:
    """(m, m) adjacency of the cells that share a facet."""
    facet_ids, unique, counts = facet_table(cells)
    owner = np.repeat(np.arange(len(cells)), cells.shape[1])
    order = np.argsort(facet_ids.ravel(), kind="stable")
    shared = counts[facet_ids.ravel()[order]] == 2
    pairs = owner[order][shared].reshape(-1, 2)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(cells),) * 2)
    return graph.tocsr()


def components(cells: np.ndarray) -> np.ndarray:
    """(m,) label of the facet-connected component of each cell, 0 .. n_components - 1."""
    if len(cells) == 0:
        return np.zeros(0, np.int64)
    return csgraph.connected_components(cell_graph(cells), directed=False)[1]


def faces_of(simplices: np.ndarray, size: int) -> np.ndarray:
    """(m, C(j, size), size) the faces with ``size`` vertices of each of the (m, j) simplices."""
    return np.stack([simplices[:, list(c)] for c in combinations(range(simplices.shape[1]), size)], axis=1)


def count_faces(simplices: np.ndarray, size: int, n_points: int) -> np.ndarray:
    """(n_points,) how many distinct faces with ``size`` vertices of ``simplices`` hold each point."""
    unique, _, _ = unique_rows(faces_of(simplices, size).reshape(-1, size))
    return np.bincount(unique.ravel(), minlength=n_points)


def pinched_ridges(cells: np.ndarray) -> np.ndarray:
    """(r, k - 1) the ridges around which the cells form two or more separate fans (a non-manifold boundary).

    Around a ridge the cells that hold it are linked through the interior facets that hold it: a closed ring (#cells
    = #facets) or a single open fan (#cells = #facets + 1) is manifold.
    """
    k = cells.shape[1] - 1
    _, facets, counts = facet_table(cells)
    cell_ridges = faces_of(cells, k - 1).reshape(-1, k - 1)
    facet_ridges = faces_of(facets[counts == 2], k - 1).reshape(-1, k - 1)
    ridges, inverse, _ = unique_rows(np.concatenate([cell_ridges, facet_ridges]))
    around = np.bincount(inverse[:len(cell_ridges)], minlength=len(ridges))
    linked = np.bincount(inverse[len(cell_ridges):], minlength=len(ridges))
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
