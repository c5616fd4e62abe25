"""Flips that raise the worst radius ratio of the cells they replace: edge removal (the ring of cells around an
interior edge triangulated again: 3-2, 4-4, 5-6 ... flips) and 2-3 flips across an interior facet (2-2 in 2D), in
passes of flips that share no cell: the sliver removal's (:mod:`bitemesh.core.optimize.slivers`).  The flips towards the
Delaunay triangulation, the relaxation's, are :mod:`bitemesh.core.optimize.delaunay_flips`.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from ..mesh.adjacency import cell_neighbours, edge_rings, facet_pairs, replaced
from ..mesh.quality import signed_radius_ratio
from ..progress import ProgressCallback, report

#: a flip must raise the worst radius ratio of the cells it replaces by at least FLIP_GAIN; only groups of cells
#: with a radius ratio below FLIP_QUALITY are tried (the others rarely gain: measured, no change in the result).
FLIP_GAIN = 1e-3
FLIP_QUALITY = 0.8
#: passes of flips in a round (each pass makes a set of flips that share no cell), and the largest ring of cells
#: around an edge that edge removal triangulates again (in 42 ways for 7).
FLIP_PASSES = 12
MAX_RING = 7
#: the edges whose rings' new cells are measured at once.
RING_CHUNK = 16384


def polygon_triangulations(n: int):
    """The triangulations of a convex polygon with vertices 0 .. n - 1.

    Returns
    -------
    triangles : (t, 3) int64, every triangle (i < j < l) of the polygon, in the polygon's orientation
    triangulations : (T, n - 2) int64, the rows of ``triangles`` that make up each triangulation (1, 2, 5, 14, 42
        of them for n = 3 .. 7)
    """
    triangles = np.array(list(combinations(range(n), 3)), dtype=np.int64)
    row = {tuple(t): i for i, t in enumerate(triangles.tolist())}

    def triangulate(vertices):
        if len(vertices) < 3:
            return [[]]
        first, last = vertices[0], vertices[-1]
        return [left + [row[(first, apex, last)]] + right
                for split, apex in enumerate(vertices[1:-1], start=1)
                for left in triangulate(vertices[:split + 1]) for right in triangulate(vertices[split:])]
    return triangles, np.array(triangulate(list(range(n))), dtype=np.int64)


RING_TRIANGULATIONS = {n: polygon_triangulations(n) for n in range(3, MAX_RING + 1)}


def _ring_cells(a: np.ndarray, b: np.ndarray, ring: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(E, t, 2, 4): for each triangle (x, y, z) of the ring's polygon, the cells (x, y, z, b) and (x, z, y, a)
    that replace those around the edge (a, b)."""
    x, y, z = (ring[:, triangles[:, i]] for i in range(3))
    apex_b, apex_a = (np.broadcast_to(v[:, None], x.shape) for v in (b, a))
    return np.stack([np.stack([x, y, z, apex_b], axis=-1), np.stack([x, z, y, apex_a], axis=-1)], axis=2)


def _best_triangulations(points: np.ndarray, a: np.ndarray, b: np.ndarray, ring: np.ndarray):
    """For the (E,) edges (a, b) with the (E, n) ``ring`` around each: the best triangulation of each ring's polygon
    (E,) (a row of ``RING_TRIANGULATIONS[n]``) and the worst radius ratio of the cells it makes (E,).  The new
    cells are measured ``RING_CHUNK`` edges at a time (their (E, t, 2, 4) table would take 2.2 kB an edge at 7)."""
    triangles, triangulations = RING_TRIANGULATIONS[ring.shape[1]]
    best, worst_new = np.zeros(len(a), np.int64), np.empty(len(a))
    for first in range(0, len(a), RING_CHUNK):
        part = slice(first, first + RING_CHUNK)
        new = _ring_cells(a[part], b[part], ring[part], triangles)
        worst = signed_radius_ratio(points, new.reshape(-1, 4)).reshape(new.shape[:3]).min(axis=2)
        by_triangulation = worst[:, triangulations].min(axis=2)  # (e, T)
        best[part] = np.argmax(by_triangulation, axis=1)
        worst_new[part] = by_triangulation[np.arange(len(new)), best[part]]
    return best, worst_new


def _across(a: np.ndarray, b: np.ndarray, facet: np.ndarray) -> np.ndarray:
    """The cells that replace the two on ``facet`` (p, k) with far vertices a, b: (p, 3, 4) around the edge (a, b)
    in 3D (2-3 flip), (p, 2, 3) in 2D (2-2 flip)."""
    if facet.shape[1] == 3:
        return np.stack([np.stack([a, b, facet[:, i], facet[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1)
    return np.stack([np.stack([a, facet[:, 0], b], axis=1), np.stack([b, facet[:, 1], a], axis=1)], axis=1)


def flip_candidates(points: np.ndarray, cells: np.ndarray, quality: np.ndarray, across: np.ndarray,
                    fresh: np.ndarray | None = None):
    """The flips that raise the worst radius ratio of the cells they replace by more than ``FLIP_GAIN``, among
    the groups of cells whose worst radius ratio is below ``FLIP_QUALITY``; with ``fresh`` ((m,) bool), only among
    the groups that hold a fresh cell.  ``across``: the cells' neighbours
    (:func:`~bitemesh.core.mesh.adjacency.cell_neighbours`).

    After a pass of :func:`flip`, every candidate either flipped or lost a cell to a flip, so a group of cells
    that were all there before gives no candidate now (the nodes do not move): only the groups with a cell made by
    the pass need testing, and they give the same candidates, in the same order, as testing all.

    3D: edge removal (the n cells around an interior edge by the 2 (n - 2) cells of the best triangulation of
    their ring joined to both ends of the edge; n = 3 is the 3-2 flip, n = 4 the 4-4 flip) and 2-3 flips (the two
    cells on an interior facet by three around the edge joining their far vertices).  2D: 2-2 flips.  Every new
    cell must be positively oriented, so the new cells fill exactly the old ones' place.

    Returns
    -------
    list of (old (c, j) cell indices, new (c, j', k + 1) cells, gain (c,)), one entry per kind of flip
    """
    k = points.shape[1]
    found = []
    if k == 3:
        for n, (a, b, ring, around) in edge_rings(cells, across, MAX_RING, fresh, quality < FLIP_QUALITY).items():
            best, worst_new = _best_triangulations(points, a, b, ring)
            gain = worst_new - quality[around].min(axis=1)
            keep = gain > FLIP_GAIN
            triangles, triangulations = RING_TRIANGULATIONS[n]
            new = _ring_cells(a[keep], b[keep], ring[keep], triangles)
            chosen = new[np.arange(len(new))[:, None], triangulations[best[keep]]].reshape(-1, 2 * (n - 2), 4)
            found.append((around[keep], chosen, gain[keep]))
    cell_a, cell_b, a, b, facet = facet_pairs(cells, across, fresh, quality < FLIP_QUALITY)
    worst_old = np.minimum(quality[cell_a], quality[cell_b])
    new = _across(a, b, facet)
    gain = signed_radius_ratio(points, new.reshape(-1, k + 1)).reshape(new.shape[:2]).min(axis=1) - worst_old
    keep = gain > FLIP_GAIN
    found.append((np.stack([cell_a, cell_b], axis=1)[keep], new[keep], gain[keep]))
    return found


def independent_flips(candidates: list, n_cells: int) -> np.ndarray:
    """(c,) bool over all candidates in order: flips that share no cell, the largest gains first.

    In rounds, a candidate wins when its gain is the largest among the candidates that share a cell with it; the
    candidates that touch a winner's cells drop out.  Each round settles at least the largest gain left.
    """
    gains = np.concatenate([gain for _, _, gain in candidates])
    offsets = np.cumsum([0] + [len(gain) for _, _, gain in candidates])
    owners = np.concatenate([np.repeat(np.arange(len(old)) + offset, old.shape[1])
                             for (old, _, _), offset in zip(candidates, offsets)])
    touched = np.concatenate([old.ravel() for old, _, _ in candidates])
    key = gains + 1e-12 * np.arange(len(gains)) / max(len(gains), 1)  # no ties
    active = np.ones(len(gains), bool)
    chosen = np.zeros(len(gains), bool)
    for _ in range(len(gains)):
        if not active.any():
            break
        live = active[owners]
        best = np.full(n_cells, -np.inf)
        np.maximum.at(best, touched[live], key[owners[live]])
        beaten = np.zeros(len(gains), bool)
        beaten[owners[live & (best[touched] > key[owners])]] = True
        winners = active & ~beaten
        chosen |= winners
        used = np.zeros(n_cells, bool)
        used[touched[winners[owners]]] = True
        blocked = np.zeros(len(gains), bool)
        blocked[owners[used[touched]]] = True
        active &= ~blocked
    return chosen


def flip(points: np.ndarray, cells: np.ndarray, passes: int = FLIP_PASSES,
         progress: ProgressCallback = None) -> np.ndarray:
    """Apply improving flips (:func:`flip_candidates`), pass after pass, until none is left (at most ``passes``).

    Flips replace cells inside the domain only: the boundary, the nodes and the volume stay as they are.

    Returns
    -------
    (m', k + 1) int64, the new cells, positively oriented
    """
    measured = signed_radius_ratio(points, cells)
    across = cell_neighbours(cells)
    fresh = None  # the first pass tests every group, each next one those with a cell the pass before made
    for pass_ in range(passes):
        candidates = flip_candidates(points, cells, measured, across, fresh)
        found = sum(len(gain) for _, _, gain in candidates)
        report(progress, pass_ / passes, f"flip pass {pass_ + 1}: {found} improving flips")
        if not found:
            break
        chosen = independent_flips(candidates, len(cells))
        removed = np.zeros(len(cells), bool)
        added = []
        start = 0
        for old, new, gain in candidates:
            take = chosen[start:start + len(gain)]
            start += len(gain)
            removed[old[take].ravel()] = True
            added.append(new[take].reshape(-1, cells.shape[1]))
        cells, across = replaced(cells, across, removed, np.concatenate(added))
        fresh = np.arange(len(cells)) >= len(cells) - sum(len(new) for new in added)
        measured = np.concatenate([measured[~removed]] + [signed_radius_ratio(points, new) for new in added])
    return cells
