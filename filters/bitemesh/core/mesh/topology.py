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
from ..compiled import kernel
from .simplicial import facet_corners, facet_of, facets_of


def unique_rows(rows: np.ndarray):
    """Group rows of vertex indices that hold the same vertices, whatever their order.

    Returns
    -------
    unique : (u, j) int64, each distinct row once, sorted
    inverse : (r,) int64, the group of each input row
    counts : (u,) int64, the size of each group
    """
    rows = rows.reshape(-1, rows.shape[-1])
    unique, inverse, counts = face_groups(rows, np.arange(rows.shape[1])[None])
    return unique, inverse.ravel(), counts


def first_rows(haystack: np.ndarray, needles: np.ndarray) -> np.ndarray:
    """For each row of ``needles`` (r, j) the index of the first equal row of ``haystack`` (h, j), or -1."""
    _, inverse = np.unique(np.concatenate([haystack, needles]), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    first = np.full(int(inverse.max(initial=-1)) + 1, -1, dtype=np.int64)
    first[inverse[:len(haystack)][::-1]] = np.arange(len(haystack))[::-1]
    return first[inverse[len(haystack):]]


def face_groups(simplices: np.ndarray, corners: np.ndarray, inverse: bool = True):
    """The distinct faces of (m, j) ``simplices`` whose vertices are at the positions ``corners`` (f, size) of
    each, without a table of every face where they are many.

    Returns
    -------
    unique : (u, size) int64, each distinct face once, vertices sorted, rows sorted
    inverse : (m, f) int64, the group of face q of simplex c (None when not asked for)
    counts : (u,) int64, how many (simplex, face) pairs are each
    """
    simplices = np.ascontiguousarray(simplices, dtype=np.int64)
    corners = np.ascontiguousarray(corners, dtype=np.int64)
    m, (f, size) = len(simplices), corners.shape
    n_points = int(simplices.max()) + 1 if simplices.size else 1
    if float(n_points) ** (size - 1) < 2.0**63 and m * f >= n_points:
        # many faces on few vertices: grouped by their lowest vertex in linear time
        unique, groups, counts = _grouped_faces(simplices, corners, n_points, inverse)
        return unique, groups.reshape(m, f) if inverse else None, counts
    rows = np.sort(simplices[:, corners].reshape(-1, size), axis=1)
    if float(n_points) ** size >= 2.0**63:   # no exact int64 key per sorted row
        unique, groups, counts = np.unique(rows, axis=0, return_inverse=True, return_counts=True)
    else:
        keys = rows[:, 0].copy()
        for column in range(1, size):
            keys = keys * n_points + rows[:, column]
        _, first, groups, counts = np.unique(keys, return_index=True, return_inverse=True, return_counts=True)
        unique = rows[first]
    return unique, groups.reshape(m, f) if inverse else None, counts


@kernel
def sorted_by(items, key):
    """(n,) ``items`` (distinct indices into ``key``) ordered by (key[item], item): a bottom-up merge sort (the
    order is strict, so any sort gives it; numba's own mergesort, which this replaces, took 2 s of a first run to
    compile).  ``sorted_by(np.arange(n), key)`` is ``np.argsort(key, kind="stable")``."""
    source, target = items.copy(), np.empty_like(items)
    width = 1
    while width < items.size:
        for left in range(0, items.size, 2 * width):
            middle, right = min(left + width, items.size), min(left + 2 * width, items.size)
            i, j = left, middle
            for out in range(left, right):
                a, b = source[i] if i < middle else -1, source[j] if j < right else -1
                if b < 0 or (a >= 0 and (key[a] < key[b] or (key[a] == key[b] and a < b))):
                    target[out] = a
                    i += 1
                else:
                    target[out] = b
                    j += 1
        source, target = target, source
        width *= 2
    return source


@kernel
def _grouped_faces(simplices: np.ndarray, corners: np.ndarray, n_points: int, with_inverse: bool):
    """:func:`face_groups` in linear time: each face's other vertices as one word (base ``n_points``), bucketed by
    its lowest vertex (a counting sort), each bucket sorted; groups numbered in that order, which is the sorted
    order of the faces.  The inverse is (m f,), empty without ``with_inverse``."""
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
    origin = np.empty(m * faces if with_inverse else 0, np.int64)
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
            if with_inverse:
                origin[fill[face[0]]] = c * faces + q
            fill[face[0]] += 1
    inverse = np.empty(m * faces if with_inverse else 0, np.int64)
    low, key, counts = np.empty(m * faces, np.int64), np.empty(m * faces, np.int64), np.empty(m * faces, np.int64)
    group = -1   # the arrays of the groups are filled as far as the groups go: only those pages are touched
    for v in range(n_points):
        bucket = rest[start[v]:start[v + 1]]
        order = sorted_by(np.arange(len(bucket)), bucket)
        for i in range(len(order)):
            if i == 0 or bucket[order[i]] != bucket[order[i - 1]]:
                group += 1
                low[group], key[group], counts[group] = v, bucket[order[i]], 0
            counts[group] += 1
            if with_inverse:
                inverse[origin[start[v] + order[i]]] = group
    unique = np.empty((group + 1, size), np.int64)
    for g in range(group + 1):
        unique[g, 0], word = low[g], key[g]
        for a in range(size - 1, 0, -1):
            unique[g, a] = word % n_points
            word //= n_points
    return unique, inverse, counts[:group + 1].copy()


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


def distinct_faces(simplices: np.ndarray, size: int) -> np.ndarray:
    """(u, size) int64, each distinct face with ``size`` vertices of ``simplices`` once, vertices sorted, rows
    sorted."""
    return face_groups(simplices, list(combinations(range(simplices.shape[1]), size)), inverse=False)[0]


def euler_characteristic(simplices: np.ndarray) -> int:
    """Euler characteristic (vertices - edges + triangles - ...) of the complex that ``simplices`` (m, k + 1) span."""
    return sum((-1) ** (size - 1) * len(distinct_faces(simplices, size)) for size in range(1, simplices.shape[1] + 1))


def non_manifold_faces(cells: np.ndarray, n_points: int) -> list:
    """The faces (arrays of (b, size) vertex ids) at which the domain is not a manifold with boundary: the
    pinched ridges, then the pinched lower faces, larger first (see :meth:`CellComplex.non_manifold_faces`)."""
    return CellComplex(cells, n_points).non_manifold_faces(np.ones(len(cells), bool))


def boundary_stars(facets: np.ndarray, n_points: int, ridges=None) -> np.ndarray:
    """(n_points,) how many stars the boundary ``facets`` (b, k) form at each vertex: the facets holding it, joined
    across the ridges (k - 1 vertices) that hold it too; 1 on a manifold boundary (a fan in 3D), 0 off it.
    ``ridges``: (corners (f, k - 1), inverse (b, f)) of :func:`face_groups` on the facets, when at hand."""
    size = facets.shape[1]
    if ridges is None:
        corners = np.array(list(combinations(range(size), size - 1)))
        ridges = corners, face_groups(facets, corners)[1]
    corners, inverse = ridges
    # Nodes of the graph are corners (size t + j: vertex j of facet t); two facets sharing a ridge join their
    # corners at each of its vertices.
    joined = []
    for row in neighbour_pairs(inverse.ravel()):
        facet, ridge = row // len(corners), row % len(corners)
        position = corners[ridge]                                                  # (p, size - 1)
        order = np.argsort(facets[facet[:, None], position], axis=1, kind="stable")   # by vertex: aligned
        joined.append(size * facet[:, None] + np.take_along_axis(position, order, axis=1))
    links = np.stack([joined[0].ravel(), joined[1].ravel()])
    graph = sparse.coo_matrix((np.ones(links.shape[1]), (links[0], links[1])), shape=(size * len(facets),) * 2)
    n_stars, labels = csgraph.connected_components(graph, directed=False)
    vertex_of_star = np.empty(n_stars, dtype=np.int64)
    vertex_of_star[labels] = facets.ravel()
    return np.bincount(vertex_of_star, minlength=n_points)


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
        self.facets, self.facet_ids, self.hull_counts = face_groups(cells, facet_corners(k + 1))
        self.neighbour_rows = neighbour_pairs(self.facet_ids.ravel())
        self.ridges, self.cell_ridges, _ = face_groups(cells, list(combinations(range(k + 1), k - 1)))
        self.incidence = vertex_incidence(n_points, cells)
        self._lower, self._subs = {}, {}   # face tables below the ridges, and faces' sub-faces, made when asked
        self._facet_ridges = self._sub_faces(k, k - 1)   # the ridges of each distinct facet

    def facet_counts(self, keep: np.ndarray) -> np.ndarray:
        """(u,) how many of the kept cells hold each facet (1: on their boundary, 2: inside)."""
        return np.bincount(self.facet_ids[keep].ravel(), minlength=len(self.facets))

    def surface_pieces(self, keep: np.ndarray) -> int:
        """How many parts the boundary of ``cells[keep]`` has: its facets joined through shared ridges, as
        :func:`connected_components` of :func:`boundary_facets` counts them."""
        boundary = np.flatnonzero(self.facet_counts(keep) == 1)
        if not len(boundary):
            return 0
        ridges, joined = np.unique(self._facet_ridges[boundary], return_inverse=True)
        facets = np.repeat(np.arange(len(boundary)), self._facet_ridges.shape[1])
        labels = _labels(facets, len(boundary) + joined.ravel(), len(boundary) + len(ridges))
        return len(np.unique(labels[:len(boundary)]))

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
        closed ring (#cells = #facets) or a single open fan (#cells = #facets + 1) is manifold.  Pinched lower faces
        (vertices in 3D; edges and vertices in 4D): a face's link is a sphere inside the domain and a ball on its
        boundary, so its Euler characteristic, the alternating count of the kept faces that hold it, must be
        1 + (-1)^(k - size) inside and 1 on the boundary (two parts, or an annulus, fail it).  When nothing else is
        found, boundary vertices whose boundary facets form more than one star (a link in pieces whose Euler
        characteristics add up right, as a ball and a solid torus in 4-D: the validity check's test).
        """
        counts = self.facet_counts(keep)
        around = np.bincount(self.cell_ridges[keep].ravel(), minlength=len(self.ridges))
        pairs = np.repeat(np.maximum(counts - 1, 0), self._facet_ridges.shape[1])   # interior facets, per ridge
        linked = np.bincount(self._facet_ridges.ravel(), pairs, minlength=len(self.ridges))
        found = [self.ridges[around - linked >= 2]]
        k = self.cells.shape[1] - 1
        held = {size: self._held(size, keep) for size in range(2, k + 2)}
        for size in range(k - 2, 0, -1):
            holding = {larger: np.bincount(self._sub_faces(larger, size)[held[larger]].ravel(),
                                           minlength=len(self._faces(size))) for larger in range(size + 1, k + 2)}
            faces, in_cells = self._faces(size), holding[k + 1]
            euler = sum((-1) ** (larger - size - 1) * count for larger, count in holding.items())
            on_boundary = np.bincount(self._sub_faces(k, size)[counts == 1].ravel(), minlength=len(faces)) > 0
            found.append(faces[(in_cells > 0) & (euler != np.where(on_boundary, 1, 1 + (-1) ** (k - size)))])
        found = [faces for faces in found if len(faces)]
        if not found and k > 2:   # a link of the right Euler characteristic in pieces (a ball and a solid torus)
            stars = boundary_stars(self.facets[counts == 1], self.n_points)
            found = [np.flatnonzero(stars > 1)[:, None]] if (stars > 1).any() else []
        return found

    def _corners(self, size: int) -> np.ndarray:
        """(f, size) the positions in a cell of its faces with ``size`` vertices, in the order of their tables."""
        corners = self.cells.shape[1]
        if size == corners - 1:
            return facet_corners(corners)
        return np.array(list(combinations(range(corners), size)), np.int64).reshape(-1, size)

    def _faces(self, size: int) -> np.ndarray:
        """(u, size) the distinct faces with ``size`` vertices (the cells, the facets, the ridges, or lower)."""
        return self._table(size)[0]

    def _table(self, size: int):
        """(distinct faces (u, size), the face ids of each cell (m, f)) for faces with ``size`` vertices."""
        k = self.cells.shape[1] - 1
        if size == k + 1:
            return self.cells, np.arange(len(self.cells))[:, None]
        if size == k:
            return self.facets, self.facet_ids
        if size == k - 1:
            return self.ridges, self.cell_ridges
        if size not in self._lower:
            self._lower[size] = face_groups(self.cells, self._corners(size))[:2]
        return self._lower[size]

    def _sub_faces(self, size: int, sub: int) -> np.ndarray:
        """(u, C(size, sub)) the ids of the faces with ``sub`` vertices of each distinct face with ``size``."""
        if (size, sub) not in self._subs:
            ids, sub_ids = self._table(size)[1], self._table(sub)[1]
            position = {tuple(sorted(corner)): q for q, corner in enumerate(self._corners(sub).tolist())}
            local = np.array([[position[tuple(sorted(c))] for c in combinations(corner, sub)]
                              for corner in self._corners(size).tolist()], np.int64)
            row = np.zeros(int(ids.max()) + 1, np.int64)
            row[ids.ravel()] = np.arange(ids.size)   # a (cell, face) of each distinct face (any will do)
            cell, face = np.divmod(row, ids.shape[1])
            self._subs[size, sub] = sub_ids[cell[:, None], local[face]]
        return self._subs[size, sub]

    def _held(self, size: int, keep: np.ndarray) -> np.ndarray:
        """(u,) bool: the distinct faces with ``size`` vertices that a kept cell holds."""
        held = np.zeros(len(self._faces(size)), bool)
        held[self._table(size)[1][keep].ravel()] = True
        return held
