"""Handles of a domain that should have none, cut or filled where they are thinnest.

A domain meant to be a ball with its cavities open (the myocardium) can come out of the Delaunay cells with
handles: a bridge thinner than a cell across a cavity, a tunnel through a wall where two fitted surfaces nearly
touch.  Two growths find where each handle can be broken.  The kept cells, grown from the deepest one in order of
decreasing f and each taken only when the grown set stays contractible (a *simple* cell), leave out a few cells on
each handle where f is lowest: a cut.  The dropped cells, grown from the convex hull in order of increasing f, leave
out a few across each tunnel where f is highest: a fill.  These clusters are tried, the shallowest first, and each
is kept when it removes a handle and changes nothing else (the parts, the boundary surfaces).
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from ..grid.sampled import ImplicitGrid
from ..mesh.simplicial import signed_measures
from ..mesh.topology import CellComplex, boundary_facets, connected_components, euler_change, euler_characteristic

#: the six edges of a tetrahedron, as pairs of its vertex positions.
TETRAHEDRON_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
#: clusters tried at most, per handle found.
TRIES_PER_HANDLE = 20
#: a cut or fill reaches at most this many cells' size (the edge of a regular tetrahedron of the median volume)
#: from the surface f = 0: the handles it removes are thinner than about two cells.
MAX_DEPTH = 1.0
#: the reach of a second pass, for a domain that has no handle by nature (a myocardium with its cavities open is a
#: ball): a handle up to about four cells thick is an artefact of fitted surfaces that nearly meet, and a cut or
#: fill that deep changes the domain by at most two cells' size where it lies.
THICK_DEPTH = 2.0


def handle_count(cells: np.ndarray) -> int:
    """How many handles the boundary of the tetrahedra ``cells`` (m, 4) has: its genus summed over its surfaces."""
    surface = boundary_facets(cells)
    if len(surface) == 0:
        return 0
    return int(connected_components(surface).max() + 1 - euler_characteristic(surface) // 2)


@dataclass(frozen=True)
class _Complex:
    """Every Delaunay cell's vertices, edge ids, facet ids and facet neighbours (-1: the convex hull), as lists for
    the growth's scalar loop; the facet and edge ids as arrays too."""

    vertices: list
    edges: list
    facets: list
    neighbours: list
    facet_ids: np.ndarray
    facet_counts: np.ndarray
    edge_ids: np.ndarray

    @classmethod
    def of(cls, complex_: CellComplex) -> _Complex:
        """From the tables of all the cells (its ridges are the edges, in the order of ``TETRAHEDRON_EDGES``)."""
        cells, facet_ids, edge_ids = complex_.cells, complex_.facet_ids.ravel(), complex_.cell_ridges
        first, second = complex_.neighbour_rows
        neighbours = np.full(cells.size, -1, dtype=np.int64)
        neighbours[first], neighbours[second] = second // 4, first // 4
        return cls(cells.tolist(), edge_ids.tolist(), complex_.facet_ids.tolist(),
                   neighbours.reshape(-1, 4).tolist(), facet_ids, complex_.hull_counts, edge_ids)


class _Growth:
    """A set of cells grown one simple cell at a time; counts of how many grown cells hold each face."""

    def __init__(self, complex_: _Complex, n_points: int):
        self.vertices, self.edges, self.facets = complex_.vertices, complex_.edges, complex_.facets
        self.neighbours = complex_.neighbours
        self.vertex_count = [0] * n_points
        self.edge_count = [0] * (int(complex_.edge_ids.max()) + 1)
        self.facet_count = [0] * len(complex_.facet_counts)
        self.grown = bytearray(len(self.vertices))

    def take_faces(self, vertices, edges, facets) -> None:
        """Count these faces as part of the set (the convex hull, for the outside)."""
        for v in vertices:
            self.vertex_count[v] += 1
        for e in edges:
            self.edge_count[e] += 1
        for f in facets:
            self.facet_count[f] += 1

    def is_simple(self, cell: int) -> bool:
        """Whether adding ``cell`` keeps the set's homotopy type: its boundary's part in the set is contractible
        (on the boundary sphere of a tetrahedron: nonempty, connected, Euler characteristic 1)."""
        inside = [self.vertex_count[v] > 0 for v in self.vertices[cell]]
        n_vertices = sum(inside)
        if n_vertices == 0:
            return False
        edges = [self.edge_count[e] > 0 for e in self.edges[cell]]
        n_edges = sum(edges)
        n_facets = sum(self.facet_count[f] > 0 for f in self.facets[cell])
        if n_vertices - n_edges + n_facets != 1 or n_edges < n_vertices - 1:
            return False
        if n_vertices == 4:   # 3 edges among 4 vertices: connected unless a triangle and a lone vertex
            touched = {vertex for k, pair in enumerate(TETRAHEDRON_EDGES) if edges[k] for vertex in pair}
            return len(touched) == 4
        return True

    def add(self, cell: int) -> None:
        self.grown[cell] = 1
        self.take_faces(self.vertices[cell], self.edges[cell], self.facets[cell])

    def grow(self, allowed: np.ndarray, priority: np.ndarray, start=(), *, seeds=()) -> np.ndarray:
        """Grow over the ``allowed`` cells, highest ``priority`` first, from the ``seeds`` (taken as they are) and
        the cells ``start`` (taken when simple, as every cell after them; a cell that is not is tried again when a
        neighbour joins).  Returns (m,) bool, the grown cells."""
        allowed, priority = allowed.tolist(), priority.tolist()
        heap = [(-priority[cell], cell) for cell in start]
        for seed in seeds:
            self.add(seed)
            heap += [(-priority[cell], cell) for cell in self.neighbours[seed] if cell >= 0 and allowed[cell]]
        heapq.heapify(heap)
        while heap:
            _, cell = heapq.heappop(heap)
            if self.grown[cell] or not self.is_simple(cell):
                continue
            self.add(cell)
            for neighbour in self.neighbours[cell]:
                if neighbour >= 0 and allowed[neighbour] and not self.grown[neighbour]:
                    heapq.heappush(heap, (-priority[neighbour], neighbour))
        return np.frombuffer(bytes(self.grown), dtype=np.uint8).astype(bool)


def break_handles(grid: ImplicitGrid, points: np.ndarray, complex_: CellComplex, keep: np.ndarray,
                  max_depth: float = MAX_DEPTH):
    """``keep`` with the handles of the kept cells thinner than about 2 x ``max_depth`` cells cut or filled.

    A cluster reaches into the domain (a cut) or out of it (a fill) as far as the largest |f| at its cells'
    centroids; the shallower clusters are tried first, then the smaller, and none reaching farther than
    ``max_depth`` cells' size (:data:`MAX_DEPTH`: a handle thicker is the data's, not the sampling's).  A cluster is
    kept when it raises the Euler characteristic (by one per handle it removes: a cut across two handles side by
    side removes both) and leaves the parts and the boundary surfaces as they were.
    The result may need the repair of :func:`bitemesh.core.steps.repair.repaired` (a cut can pinch the boundary).

    Parameters
    ----------
    grid : f on the grid I; points : (n, 3) float64 nodes; complex_ : the tables of every Delaunay cell (m, 4)
    keep : (m,) bool, the cells of a valid domain (a manifold boundary)

    Returns
    -------
    keep : (m,) bool; removed : int, the handles removed
    """
    cells = complex_.cells
    kept_cells = cells[keep]
    handles = handle_count(kept_cells)
    if handles == 0:
        return keep, 0
    growth_complex = _Complex.of(complex_)
    value = grid.evaluate(points[cells].mean(axis=1))
    parts = complex_.components(keep)
    cut = keep & ~_grown_inside(growth_complex, len(points), keep, value, parts)
    fill = ~keep & ~_grown_outside(growth_complex, cells, len(points), keep, value)
    cell_size = float(np.cbrt(6 * np.sqrt(2) * np.median(signed_measures(points, kept_cells))))
    candidates = [candidate for candidate in _clusters(points, cells, cut, value, fill=False)
                  + _clusters(points, cells, fill, value, fill=True) if candidate[0] <= max_depth * cell_size]
    removed, parts_before, pieces_before = 0, parts.max() + 1, _surface_pieces(kept_cells)
    for _, _, members, is_fill in sorted(candidates, key=lambda candidate: candidate[:2])[:TRIES_PER_HANDLE * handles]:
        change = euler_change(complex_.incidence, cells, keep, members, is_fill)
        if not 1 <= change <= handles - removed:
            continue
        trial = keep.copy()
        trial[members] = is_fill
        if complex_.components(trial).max() + 1 == parts_before \
                and _surface_pieces(cells[trial]) == pieces_before:
            keep, removed = trial, removed + change
            if removed == handles:
                break
    return keep, removed


def _grown_inside(complex_: _Complex, n_points: int, keep: np.ndarray, value: np.ndarray,
                  parts: np.ndarray) -> np.ndarray:
    """The kept cells grown from the deepest of each part, deepest first, each while the set stays contractible."""
    kept = np.flatnonzero(keep)
    deepest = [int(kept[parts == part][np.argmax(value[kept[parts == part]])]) for part in range(parts.max() + 1)]
    return _Growth(complex_, n_points).grow(keep, value, seeds=deepest)


def _grown_outside(complex_: _Complex, cells: np.ndarray, n_points: int, keep: np.ndarray,
                   value: np.ndarray) -> np.ndarray:
    """The dropped cells grown from the convex hull (the outside, a ball in the 3-sphere), farthest out first."""
    growth = _Growth(complex_, n_points)
    facet_ids, facet_counts, edge_ids = complex_.facet_ids, complex_.facet_counts, complex_.edge_ids
    hull = np.flatnonzero(facet_counts[facet_ids] == 1)   # rows c * 4 + i: facet i (opposite vertex i) of cell c
    hull_cells, opposite = hull // 4, hull % 4
    edges_without = np.array([[k for k, pair in enumerate(TETRAHEDRON_EDGES) if i not in pair] for i in range(4)])
    growth.take_faces(np.unique(cells[hull_cells][np.arange(4) != opposite[:, None]]).tolist(),
                      np.unique(edge_ids[hull_cells[:, None], edges_without[opposite]]).tolist(),
                      facet_ids[hull].tolist())
    on_hull = np.unique(hull_cells)
    return growth.grow(~keep, -value, on_hull[~keep[on_hull]].tolist())


def _clusters(points, cells, members: np.ndarray, value: np.ndarray, *, fill: bool) -> list:
    """(depth, volume, cell indices, fill) of each facet-connected cluster of the ``members`` cells; depth: the
    largest |f| at their centroids."""
    index = np.flatnonzero(members)
    if len(index) == 0:
        return []
    labels = connected_components(cells[index])
    volume = np.bincount(labels, weights=signed_measures(points, cells[index]))
    depth = np.zeros(len(volume))
    np.maximum.at(depth, labels, np.abs(value[index]))
    return [(float(depth[label]), float(volume[label]), index[labels == label], fill) for label in range(len(volume))]


def _surface_pieces(cells: np.ndarray) -> int:
    surface = boundary_facets(cells)
    return int(connected_components(surface).max() + 1) if len(surface) else 0
