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

from ..compiled import kernel
from ..grid.sampled import ImplicitGrid
from ..mesh.simplicial import facet_corners, regular_edge, signed_measures
from ..mesh.topology import CellComplex, boundary_facets, connected_components, euler_change, euler_characteristic

#: the six edges of a tetrahedron, as pairs of its vertex positions.
TETRAHEDRON_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
#: a cut or fill has at most this many cells: one across a handle up to four cells thick (THICK_DEPTH) and about 20
#: cells (40 mm at R = 2 mm) wide.  A larger one runs along a wall instead of across a handle: biv-me patient1's
#: frame 14 lost its RV free wall from the base to the apex to a cut of 1,300 cells (the RV cavity open along it,
#: 63 ml against biv-me's 148), frame 9 to one of 641, where fills of 111 and 88 cells remove the same handles.
MAX_CELLS = 400
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
    """Every Delaunay cell's vertices (m, 4), edge ids (m, 6, in the order of ``TETRAHEDRON_EDGES``), facet ids
    (m, 4) and facet neighbours (m, 4; -1: the convex hull), int64, for the compiled growth."""

    vertices: np.ndarray
    edges: np.ndarray
    facets: np.ndarray
    neighbours: np.ndarray
    facet_counts: np.ndarray

    @classmethod
    def of(cls, complex_: CellComplex) -> _Complex:
        """From the tables of all the cells (its ridges are the edges, in the order of ``TETRAHEDRON_EDGES``)."""
        cells = complex_.cells
        first, second = complex_.neighbour_rows
        neighbours = np.full(cells.size, -1, dtype=np.int64)
        neighbours[first], neighbours[second] = second // 4, first // 4
        return cls(np.ascontiguousarray(cells, np.int64), np.ascontiguousarray(complex_.cell_ridges, np.int64),
                   np.ascontiguousarray(complex_.facet_ids, np.int64), neighbours.reshape(-1, 4),
                   complex_.hull_counts)


class _Growth:
    """A set of cells grown one simple cell at a time; counts of how many grown cells hold each face."""

    def __init__(self, complex_: _Complex, n_points: int):
        self.complex = complex_
        self.vertex_count = np.zeros(n_points, np.int64)
        self.edge_count = np.zeros(int(complex_.edges.max()) + 1, np.int64)
        self.facet_count = np.zeros(len(complex_.facet_counts), np.int64)
        self.grown = np.zeros(len(complex_.vertices), np.bool_)

    def take_faces(self, vertices: np.ndarray, edges: np.ndarray, facets: np.ndarray) -> None:
        """Count these faces (distinct ids) as part of the set (the convex hull, for the outside)."""
        self.vertex_count[vertices] += 1
        self.edge_count[edges] += 1
        self.facet_count[facets] += 1

    def grow(self, allowed: np.ndarray, priority: np.ndarray, start=(), *, seeds=()) -> np.ndarray:
        """Grow over the ``allowed`` cells, highest ``priority`` first, from the ``seeds`` (taken as they are) and
        the cells ``start`` (taken when simple, as every cell after them; a cell that is not is tried again when a
        neighbour joins).  Returns (m,) bool, the grown cells."""
        c = self.complex
        _grow(c.vertices, c.edges, c.facets, c.neighbours, self.vertex_count, self.edge_count, self.facet_count,
              self.grown, np.asarray(allowed, np.bool_), np.asarray(priority, np.float64),
              np.asarray(start, np.int64), np.asarray(seeds, np.int64), np.array(TETRAHEDRON_EDGES, np.int64))
        return self.grown.copy()


@kernel
def _grow(vertices, edges, facets, neighbours, vertex_count, edge_count, facet_count, grown, allowed, priority,
          start, seeds, tetrahedron_edges):
    """:meth:`_Growth.grow`: a heap of (-priority, cell), a cell taken when simple (adding it keeps the set's
    homotopy type: its boundary's part in the set is nonempty, connected and of Euler characteristic 1)."""
    heap = [(-priority[cell], cell) for cell in start]
    for seed in seeds:
        _take(seed, vertices, edges, facets, vertex_count, edge_count, facet_count, grown)
        for neighbour in neighbours[seed]:
            if neighbour >= 0 and allowed[neighbour]:
                heap.append((-priority[neighbour], neighbour))
    heapq.heapify(heap)
    while len(heap):
        _, cell = heapq.heappop(heap)
        if grown[cell]:
            continue
        n_vertices = n_edges = n_facets = 0
        for q in range(4):
            n_vertices += vertex_count[vertices[cell, q]] > 0
            n_facets += facet_count[facets[cell, q]] > 0
        touched = np.zeros(4, np.bool_)
        for q in range(6):
            if edge_count[edges[cell, q]] > 0:
                n_edges += 1
                touched[tetrahedron_edges[q, 0]] = touched[tetrahedron_edges[q, 1]] = True
        if n_vertices == 0 or n_vertices - n_edges + n_facets != 1 or n_edges < n_vertices - 1:
            continue
        if n_vertices == 4 and not touched.all():   # 3 edges among 4 vertices: a triangle and a lone vertex
            continue
        _take(cell, vertices, edges, facets, vertex_count, edge_count, facet_count, grown)
        for neighbour in neighbours[cell]:
            if neighbour >= 0 and allowed[neighbour] and not grown[neighbour]:
                heapq.heappush(heap, (-priority[neighbour], neighbour))


@kernel
def _take(cell, vertices, edges, facets, vertex_count, edge_count, facet_count, grown):
    grown[cell] = True
    for q in range(4):
        vertex_count[vertices[cell, q]] += 1
        facet_count[facets[cell, q]] += 1
    for q in range(6):
        edge_count[edges[cell, q]] += 1


def break_handles(grid: ImplicitGrid, points: np.ndarray, complex_: CellComplex, keep: np.ndarray,
                  max_depth: float = MAX_DEPTH, surface_of=None):
    """``keep`` with the handles of the kept cells thinner than about 2 x ``max_depth`` cells cut or filled.

    A cluster reaches into the domain (a cut) or out of it (a fill) as far as the largest |f| at its cells'
    centroids; the shallower clusters are tried first, then the smaller, and none reaching farther than
    ``max_depth`` cells' size (:data:`MAX_DEPTH`: a handle thicker is the data's, not the sampling's) or larger
    than :data:`MAX_CELLS` cells (a strip along a wall, not across a handle).  A cluster is
    kept when it raises the Euler characteristic (by one per handle it removes: a cut across two handles side by
    side removes both) and leaves the parts and the boundary surfaces as they were; with ``surface_of``, a cut
    touches the boundary on one of the data's surfaces at most (:func:`_joins_surfaces`).
    The result may need the repair of :func:`bitemesh.core.steps.repair.repaired` (a cut can pinch the boundary).

    Parameters
    ----------
    grid : f on the grid I; points : (n, 3) float64 nodes; complex_ : the tables of every Delaunay cell (m, 4)
    keep : (m,) bool, the cells of a valid domain (a manifold boundary)
    surface_of : callable (b, 3) points -> (b,) int, which of the data's surfaces gives f there (-1: none, the
        base, which a cut may touch too), or None

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
    cell_size = regular_edge(float(np.median(signed_measures(points, kept_cells))), 3)
    candidates = [candidate for candidate in _clusters(points, cells, cut, value, fill=False)
                  + _clusters(points, cells, fill, value, fill=True)
                  if candidate[0] <= max_depth * cell_size and len(candidate[2]) <= MAX_CELLS]
    removed, parts_before, pieces_before = 0, parts.max() + 1, complex_.surface_pieces(keep)
    for _, _, members, is_fill in sorted(candidates, key=lambda candidate: candidate[:2])[:TRIES_PER_HANDLE * handles]:
        change = euler_change(complex_.incidence, cells, keep, members, is_fill)
        opens_wall = not is_fill and surface_of is not None and _joins_surfaces(complex_, points, keep, members,
                                                                                 surface_of)
        if opens_wall or not 1 <= change <= handles - removed:
            continue
        trial = keep.copy()
        trial[members] = is_fill
        if complex_.components(trial).max() + 1 == parts_before \
                and complex_.surface_pieces(trial) == pieces_before:
            keep, removed = trial, removed + change
            if removed == handles:
                break
    return keep, removed


def _joins_surfaces(complex_: CellComplex, points: np.ndarray, keep: np.ndarray, members: np.ndarray,
                    surface_of) -> bool:
    """Whether the cells ``members`` touch the boundary of the kept cells on two of the data's surfaces besides the
    base: cutting them would open a cavity through its wall (its endocardium turned into the epicardium along the
    cut's rim, a hole in a heart's side) or two cavities into each other, not break a bridge across one."""
    facet_ids = complex_.facet_ids[members]
    on_boundary = complex_.facet_counts(keep)[facet_ids] == 1
    cells, opposite = np.nonzero(on_boundary)
    corners = complex_.cells[members][cells[:, None], facet_corners(4)[opposite]]
    touched = np.unique(surface_of(points[corners].mean(axis=1)))
    return np.count_nonzero(touched >= 0) > 1


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
    facet_ids, edge_ids = complex_.facets.ravel(), complex_.edges
    hull = np.flatnonzero(complex_.facet_counts[facet_ids] == 1)   # rows c * 4 + i: facet i (opposite vertex i)
    hull_cells, opposite = hull // 4, hull % 4
    edges_without = np.array([[k for k, pair in enumerate(TETRAHEDRON_EDGES) if i not in pair] for i in range(4)])
    growth.take_faces(np.unique(cells[hull_cells][np.arange(4) != opposite[:, None]]),
                      np.unique(edge_ids[hull_cells[:, None], edges_without[opposite]]), facet_ids[hull])
    on_hull = np.unique(hull_cells)
    return growth.grow(~keep, -value, on_hull[~keep[on_hull]])


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
