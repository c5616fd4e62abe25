"""Edge collapse for the sliver removal (:mod:`bitemesh.core.optimize.slivers`): a poor cell that lies flat against the
surface, every node on the boundary, sits where the surface triangulation folds over itself.  Flips keep the boundary
facets and smoothing cannot lift a cell whose nodes all lie on f = 0, so neither removes it.  Collapsing one of its
boundary edges (v, w) does: node v goes, the cells that hold v and w go with it, and w takes v's place in the others;
the surface then runs along its own edges from w, all on f = 0.  (Collapses along the cell's other edges were tried:
on the two-cavity shell at 136,000 cells they left 2 poor cells of 5, against none.)

A collapse is made only when every cell it makes is positive and its worst radius ratio beats the worst of the cells
it replaces; when the cells around it stay a manifold with boundary with the same Euler characteristic, no cell
twice, no node but the one collapsed left in no cell and no interior node brought to the surface; and when it
touches no node of another collapse in the same call (their checks stay independent).
"""
from __future__ import annotations

import numpy as np

from ..mesh.quality import signed_radius_ratio
from ..mesh.topology import (boundary_facets, distinct_faces, euler_characteristic, non_manifold_faces, unique_rows,
                             vertex_incidence)


def collapse_flat_cells(points: np.ndarray, cells: np.ndarray, candidates: np.ndarray) -> tuple:
    """Collapse a boundary edge of each of the ``candidates`` (cell indices) that lies flat against the surface.

    Parameters
    ----------
    points : (n, k) nodes; cells : (m, k + 1) positively oriented simplices, a manifold with boundary
    candidates : (c,) indices of poor cells; those with a node off the boundary are left alone

    Returns
    -------
    (points, cells): without the nodes collapsed away (the others keep their order) and the cells they took with
    them; the inputs themselves when no collapse was made
    """
    facets = boundary_facets(cells)
    on_boundary = np.zeros(len(points), bool)
    on_boundary[facets.ravel()] = True
    flat = candidates[on_boundary[cells[candidates]].all(axis=1)]
    if len(flat) == 0:
        return points, cells
    boundary_edges = {tuple(edge) for edge in distinct_faces(facets, 2).tolist()}
    incidence = vertex_incidence(len(points), cells)
    quality = signed_radius_ratio(points, cells)
    cells, alive = cells.copy(), np.ones(len(cells), bool)
    gone, busy = np.zeros(len(points), bool), np.zeros(len(points), bool)
    for cell in flat:
        if not alive[cell] or busy[cells[cell]].any():
            continue
        best = _best_collapse(points, cells, alive, quality, incidence, cells[cell], boundary_edges)
        if best is None:
            continue
        v, region, changed, made, removed = best
        nodes = np.unique(cells[region])
        if busy[nodes].any() or not _still_manifold(cells, alive, incidence, nodes, changed, made, removed):
            continue
        cells[changed], alive[removed], gone[v] = made, False, True
        quality[changed] = signed_radius_ratio(points, made)
        busy[cells[region].ravel()] = True
    if not gone.any():
        return points, cells
    renumber = np.cumsum(~gone) - 1
    return points[~gone], renumber[cells[alive]]


def _best_collapse(points, cells, alive, quality, incidence, cell, boundary_edges):
    """Of the collapses v -> w along the boundary edges of ``cell`` (sorted pairs in ``boundary_edges``), the one
    whose worst new cell is best, if it beats the worst of the cells around v: (v, the alive cells around v and w,
    the cells changed, their new rows, the cells removed); None when none does."""
    best, best_worst = None, -np.inf
    for v in cell:
        around_v = incidence[v].indices[alive[incidence[v].indices]]
        for w in cell:
            if v == w or (min(v, w), max(v, w)) not in boundary_edges:
                continue
            holds_w = (cells[around_v] == w).any(axis=1)
            changed = around_v[~holds_w]
            made = np.where(cells[changed] == v, w, cells[changed])
            worst = signed_radius_ratio(points, made).min() if len(made) else np.inf
            if worst > quality[around_v].min() and worst > best_worst:
                around_w = incidence[w].indices[alive[incidence[w].indices]]
                best, best_worst = (v, np.union1d(around_v, around_w), changed, made, around_v[holds_w]), worst
    return best


def _still_manifold(cells, alive, incidence, nodes, changed, made, removed) -> bool:
    """Whether the alive cells around ``nodes`` (those of the cells around v and w) are still a manifold with
    boundary with the same Euler characteristic, no cell twice, no node but v left in no cell (cine frame 6: a
    boundary node whose cells all held the edge, after which every later state was invalid) and no interior node on
    the boundary, once
    ``changed`` become ``made`` and ``removed`` go.  Only faces with a node in ``nodes`` are judged: all their
    cells are in this neighbourhood.  ``incidence`` may predate earlier collapses: none of them touched ``nodes``."""
    near = np.unique(incidence[nodes].indices)
    near = near[alive[near]]
    after = cells.copy()
    after[changed] = made
    after = after[np.setdiff1d(near, removed)]
    if len(np.setdiff1d(cells[near], after)) > 1:   # a node besides v left in no cell
        return False
    if euler_characteristic(after) != euler_characteristic(cells[near]):
        return False
    if len(unique_rows(np.sort(after, axis=1))[0]) != len(after):
        return False
    judged = np.zeros(len(incidence.indptr) - 1, bool)
    judged[nodes] = True
    if any(judged[faces].any(axis=1).any() for faces in non_manifold_faces(after, len(judged))):
        return False
    return bool(np.isin(_surface_nodes(after, judged), _surface_nodes(cells[near], judged)).all())


def _surface_nodes(cells: np.ndarray, judged: np.ndarray) -> np.ndarray:
    """The nodes of the boundary facets of ``cells`` that have a ``judged`` node (those are the mesh's own
    boundary facets: every cell around a judged node is in ``cells``)."""
    facets = boundary_facets(cells)
    return np.unique(facets[judged[facets].any(axis=1)])
