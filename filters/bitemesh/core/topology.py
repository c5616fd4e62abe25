"""Combinatorics of simplicial meshes: facets, boundary, components and the manifold tests, vectorized.

Names follow the dimension k of the cells: a *facet* has k vertices (a triangle of a tetrahedron, an edge of a
triangle), a *ridge* has k - 1 (an edge of a tetrahedron, a vertex of a triangle).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from .adjacency import BOUNDARY, cell_neighbours
from .kernels import kernel
from .mesh import facet_of, facets_of


def unique_rows(rows: np.ndarray):
    """Group rows of vertex indices that hold the same vertices, whatever their order.

    Returns
    -------
    unique : (u, j) int64, each distinct row once, sorted
    inverse : (r,) int64, the group of each input row
    counts : (u,) int64, the size of each group
    """
    rows = np.ascontiguousarray(rows.reshape(-1, rows.shape[-1]), dtype=np.int64)
    n_points = int(rows.max()) + 1 if rows.size else 1
    if float(n_points) ** (rows.shape[1] - 1) < 2.0**63 and len(rows) >= n_points:
        # many rows on few vertices: grouped by their lowest vertex in linear time
        rows, order, inverse, first = _grouped_unique(rows, n_points)
    elif float(n_points) ** rows.shape[1] >= 2.0**63:   # no exact int64 key per sorted row
        unique, inverse, counts = np.unique(np.sort(rows, axis=1), axis=0, return_inverse=True, return_counts=True)
        return unique, inverse.ravel(), counts
    else:
        rows = np.sort(rows, axis=1)
        keys = rows[:, 0].copy()
        for column in range(1, rows.shape[1]):
            keys = keys * n_points + rows[:, column]
        # np.unique's result from one unstable sort of the keys: equal keys are equal rows, so any of them will do
        order = np.argsort(keys)
        ordered = keys[order]
        start = np.empty(len(keys), bool)
        start[:1] = True
        np.not_equal(ordered[1:], ordered[:-1], out=start[1:])
        inverse = np.empty(len(keys), np.int64)
        inverse[order] = np.cumsum(start) - 1
        first = np.flatnonzero(start)
    return rows[order[first]], inverse, np.diff(np.append(first, len(rows)))


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


@kernel
def _counting_sort(values: np.ndarray, n_values: int) -> np.ndarray:
    """(r,) int64, ``np.argsort(values, kind="stable")`` of (r,) ``values`` in 0 .. n_values - 1, in linear time."""
    start = np.zeros(n_values + 1, np.int64)
    for value in values:
        start[value + 1] += 1
    for value in range(n_values):
        start[value + 1] += start[value]
    order = np.empty(len(values), np.int64)
    for i in range(len(values)):
        order[start[values[i]]] = i
        start[values[i]] += 1
    return order


@kernel
def _grouped_unique(rows: np.ndarray, n_points: int):
    """The (r, j) ``rows`` of vertex ids below ``n_points``, each sorted, then sorted and grouped as
    :func:`unique_rows` gives them: (sorted rows (r, j), order (r,), inverse (r,), the position in order of each
    group's first row (u,)).  Ordered by their lowest vertex (:func:`_counting_sort`), then within each run of
    equal lowest vertex by the rest (one word, base ``n_points``), by insertion (a vertex is the lowest of a few
    dozen faces)."""
    r, j = rows.shape
    rows = rows.copy()
    rest = np.zeros(r, np.int64)
    for i in range(r):
        for a in range(1, j):   # insertion sort of the row
            value, b = rows[i, a], a - 1
            while b >= 0 and rows[i, b] > value:
                rows[i, b + 1] = rows[i, b]
                b -= 1
            rows[i, b + 1] = value
        for a in range(1, j):
            rest[i] = rest[i] * n_points + rows[i, a]
    order = _counting_sort(rows[:, 0].copy(), n_points)
    low, ordered_rest = rows[:, 0][order], rest[order]
    inverse = np.empty(r, np.int64)
    first = np.empty(r, np.int64)
    group, begin = -1, 0
    while begin < r:
        end = begin + 1
        while end < r and low[end] == low[begin]:   # insertion sort of the run by rest
            key, row, b = ordered_rest[end], order[end], end - 1
            while b >= begin and ordered_rest[b] > key:
                ordered_rest[b + 1], order[b + 1] = ordered_rest[b], order[b]
                b -= 1
            ordered_rest[b + 1], order[b + 1] = key, row
            end += 1
        for i in range(begin, end):
            if i == begin or ordered_rest[i] != ordered_rest[i - 1]:
                group += 1
                first[group] = i
            inverse[order[i]] = group
        begin = end
    return rows, order, inverse, first[:group + 1].copy()


def neighbour_pairs(inverse: np.ndarray):
    """(a, b): the row pairs of a facet table that are the same facet, as indices into the table."""
    order = _counting_sort(inverse, int(inverse.max()) + 1 if len(inverse) else 0)
    same = inverse[order[1:]] == inverse[order[:-1]]
    return order[:-1][same], order[1:][same]


def single_facets(cells: np.ndarray) -> np.ndarray:
    """(m, k + 1) bool, True where the facet opposite vertex i of cell c is held by that cell alone."""
    return cell_neighbours(cells) == BOUNDARY


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """(b, k) the facets held by one cell only, in cell order, oriented out of the domain.

    3D: triangles (p, q, r) with (q - p) x (r - p) pointing out.  2D: edges (p, q) with the domain on the left.
    """
    return facet_of(cells, *np.nonzero(single_facets(cells)))


def connected_components(cells: np.ndarray) -> np.ndarray:
    """(m,) labels 0 .. c - 1 of the cells joined through shared facets (not through edges or vertices only)."""
    if len(cells) == 0:
        return np.zeros(0, np.int64)
    _, inverse, _ = facet_table(cells)
    a, b = neighbour_pairs(inverse)
    return _labels(a // cells.shape[1], b // cells.shape[1], len(cells))


def _labels(a: np.ndarray, b: np.ndarray, n_cells: int) -> np.ndarray:
    """(n_cells,) int64 component labels of the graph with edges (a, b), numbered by their first cell."""
    graph = sparse.coo_matrix((np.ones(len(a)), (a, b)), shape=(n_cells,) * 2)
    return csgraph.connected_components(graph, directed=False)[1].astype(np.int64)


def faces_of(simplices: np.ndarray, size: int) -> np.ndarray:
    """(m, C(j, size), size) the faces with ``size`` vertices of each of the (m, j) simplices."""
    return np.stack([simplices[:, list(c)] for c in combinations(range(simplices.shape[1]), size)], axis=1)


@kernel
def _grouped_distinct(simplices: np.ndarray, corners: np.ndarray, n_points: int) -> np.ndarray:
    """(u, size) the distinct faces of the (m, j) ``simplices`` with the local vertices ``corners`` (f, size),
    vertices and rows sorted: each face's other vertices as one word (base ``n_points``) bucketed by its lowest
    vertex, each bucket sorted and deduplicated in place (no (m f, size) table of faces)."""
    m, faces, size = len(simplices), len(corners), corners.shape[1]
    start = np.zeros(n_points + 1, np.int64)
    for c in range(m):
        for q in range(faces):
            low = simplices[c, corners[q, 0]]
            for a in range(1, size):
                low = min(low, simplices[c, corners[q, a]])
            start[low + 1] += 1
    for v in range(n_points):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    rest = np.empty(m * faces, np.int64)
    face = np.empty(size, np.int64)
    for c in range(m):
        for q in range(faces):
            for a in range(size):   # insertion sort of the face's vertices
                value, b = simplices[c, corners[q, a]], a - 1
                while b >= 0 and face[b] > value:
                    face[b + 1] = face[b]
                    b -= 1
                face[b + 1] = value
            key = 0
            for a in range(1, size):
                key = key * n_points + face[a]
            rest[fill[face[0]]] = key
            fill[face[0]] += 1
    kept = np.zeros(n_points, np.int64)
    for v in range(n_points):
        bucket = rest[start[v]:start[v + 1]]
        bucket.sort()
        for i in range(len(bucket)):
            if i == 0 or bucket[i] != bucket[i - 1]:
                bucket[kept[v]] = bucket[i]
                kept[v] += 1
    unique = np.empty((kept.sum(), size), np.int64)
    row = 0
    for v in range(n_points):
        for i in range(kept[v]):
            key = rest[start[v] + i]
            unique[row, 0] = v
            for a in range(size - 1, 0, -1):
                unique[row, a] = key % n_points
                key //= n_points
            row += 1
    return unique


def distinct_faces(simplices: np.ndarray, size: int) -> np.ndarray:
    """(u, size) int64, each distinct face with ``size`` vertices of ``simplices`` once, vertices sorted, rows
    sorted."""
    simplices = np.ascontiguousarray(simplices, dtype=np.int64)
    n_points = int(simplices.max()) + 1 if simplices.size else 1
    if float(n_points) ** (size - 1) >= 2.0**63:   # no exact int64 word for a face's other vertices
        return unique_rows(faces_of(simplices, size))[0]
    return _grouped_distinct(simplices, np.array(list(combinations(range(simplices.shape[1]), size)), np.int64),
                             n_points)


def euler_characteristic(simplices: np.ndarray) -> int:
    """Euler characteristic (vertices - edges + triangles - ...) of the complex that ``simplices`` (m, k + 1) span."""
    return sum((-1) ** (size - 1) * len(distinct_faces(simplices, size)) for size in range(1, simplices.shape[1] + 1))


def non_manifold_faces(cells: np.ndarray, n_points: int) -> list:
    """The faces (arrays of (b, size) vertex ids) at which the domain is not a manifold with boundary: the
    pinched ridges, then (3D) the pinched vertices (see :meth:`CellComplex.non_manifold_faces`)."""
    return CellComplex(cells, n_points).non_manifold_faces(np.ones(len(cells), bool))


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
    near = np.unique(incidence[np.unique(cells[changed])].indices)
    after = keep[near].copy()
    after[np.isin(near, changed)] = value
    return euler_characteristic(cells[near[after]]) - euler_characteristic(cells[near[keep[near]]])


class CellComplex:
    """The facet and ridge tables of a fixed set of cells (m, k + 1), made once, and what they say about any
    subset ``keep`` (m,) bool of them by counting alone: the same answers, in the same order, as the functions
    above on ``cells[keep]``, without sorting again (the cells must be distinct and no facet held by three).

    ``facet_ids`` (m, k + 1): the distinct facet opposite each vertex, rows of ``facets`` (u, k), sorted;
    ``hull_counts`` (u,): how many of all the cells hold each; ``neighbour_rows``: :func:`neighbour_pairs` of the
    facet rows; ``cell_ridges`` (m, C(k + 1, 2)): the ridges of each cell, rows of ``ridges``, in the order of
    :func:`faces_of`; ``incidence``: :func:`vertex_incidence`.
    """

    def __init__(self, cells: np.ndarray, n_points: int):
        self.cells, self.n_points = cells, n_points
        k = cells.shape[1] - 1
        self.facets, facet_ids, self.hull_counts = unique_rows(facets_of(cells))
        self.facet_ids = facet_ids.reshape(len(cells), k + 1)
        self.neighbour_rows = neighbour_pairs(facet_ids)
        self.ridges, ridge_ids, _ = unique_rows(faces_of(cells, k - 1))
        self.cell_ridges = ridge_ids.reshape(len(cells), -1)
        row = np.zeros(len(self.facets), np.int64)
        row[facet_ids] = np.arange(len(facet_ids))   # a row of each distinct facet (any: the same ridges)
        without = np.array([[j for j, ridge in enumerate(combinations(range(k + 1), k - 1)) if i not in ridge]
                            for i in range(k + 1)])   # the cell's ridges on the facet opposite vertex i
        self._facet_ridges = self.cell_ridges[(row // (k + 1))[:, None], without[row % (k + 1)]]
        self.incidence = vertex_incidence(n_points, cells)

    def facet_counts(self, keep: np.ndarray) -> np.ndarray:
        """(u,) how many of the kept cells hold each facet (1: on their boundary, 2: inside)."""
        return np.bincount(self.facet_ids[keep].ravel(), minlength=len(self.facets))

    def components(self, keep: np.ndarray) -> np.ndarray:
        """(kept,) the labels of :func:`connected_components` of ``cells[keep]``."""
        a, b = (rows // self.cells.shape[1] for rows in self.neighbour_rows)
        both = keep[a] & keep[b]
        local = np.cumsum(keep) - 1
        return _labels(local[a[both]], local[b[both]], int(local[-1]) + 1)

    def cells_around(self, face: np.ndarray) -> np.ndarray:
        """(c,) sorted, the cells that hold every vertex of ``face``."""
        held, times = np.unique(self.incidence[face].indices, return_counts=True)
        return held[times == len(face)]

    def non_manifold_faces(self, keep: np.ndarray) -> list:
        """The faces at which the kept cells are not a manifold with boundary, as :func:`non_manifold_faces`.

        Pinched ridges: around a ridge the kept cells are linked through the interior facets that hold it; a
        closed ring (#cells = #facets) or a single open fan (#cells = #facets + 1) is manifold.  Pinched vertices
        (3D): the link's Euler characteristic, #edges - #triangles + #cells holding the vertex, is 2 inside and 1
        on the boundary.
        """
        counts = self.facet_counts(keep)
        around = np.bincount(self.cell_ridges[keep].ravel(), minlength=len(self.ridges))
        pairs = np.repeat(np.maximum(counts - 1, 0), self._facet_ridges.shape[1])   # interior facets, per ridge
        linked = np.bincount(self._facet_ridges.ravel(), pairs, minlength=len(self.ridges))
        found = [self.ridges[around - linked >= 2]]
        if self.cells.shape[1] == 4:
            def holding(faces):
                return np.bincount(faces.ravel(), minlength=self.n_points)
            in_cells = holding(self.cells[keep])
            euler = holding(self.ridges[around > 0]) - holding(self.facets[counts > 0]) + in_cells
            on_boundary = holding(self.facets[counts == 1]) > 0
            found.append(np.flatnonzero((in_cells > 0) & (euler != np.where(on_boundary, 1, 2)))[:, None])
        return [faces for faces in found if len(faces)]
