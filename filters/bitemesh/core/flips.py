"""Flips that raise the worst radius ratio of the cells they replace: edge removal (the ring of cells around an
interior edge triangulated again: 3-2, 4-4, 5-6 ... flips) and 2-3 flips across an interior facet (2-2 in 2D), in
passes of flips that share no cell; and flips towards the Delaunay triangulation of the domain (2-3 and 3-2, 2-2
in 2D), the local update of the relaxation (:func:`bitemesh.core.relax.relax`).
"""
from __future__ import annotations

from itertools import combinations, permutations

import numpy as np

from .cell_measures import signed_radius_ratio
from .progress import ProgressCallback, report
from .mesh import circumspheres, facets_of

#: a flip must raise the worst radius ratio of the cells it replaces by at least FLIP_GAIN; only groups of cells
#: with a radius ratio below FLIP_QUALITY are tried (the others rarely gain: measured, no change in the result).
FLIP_GAIN = 1e-3
FLIP_QUALITY = 0.8
#: a Delaunay flip must take a vertex at least this fraction of the squared circumradius inside a circumsphere (far
#: above rounding: no flip and its inverse both pass).
DELAUNAY_GAIN = 1e-6
#: a cell whose radius ratio is below FLAT_QUALITY counts as flat: no Delaunay flip makes one, no move of the
#: relaxation either.  Four nodes on the base plane or on a lattice's plane are flat to rounding, and rounding (the
#: floating-point library) must not decide whether a cell is made.
FLAT_QUALITY = 1e-6
#: passes of flips in a round (each pass makes a set of flips that share no cell), and the largest ring of cells
#: around an edge that edge removal triangulates again (in 42 ways for 7).
FLIP_PASSES = 12
MAX_RING = 7


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


def _is_even(permutation) -> bool:
    return sum(a > b for a, b in combinations(permutation, 2)) % 2 == 0


#: for each edge (i, j) of a tetrahedron, the other two vertices (k, l) ordered so that (i, j, k, l) is an even
#: permutation of (0, 1, 2, 3): then (v_i, v_j, v_k, v_l) is as positively oriented as (v_0, v_1, v_2, v_3).
EDGE_PAIRS = np.array(list(combinations(range(4), 2)))
EDGE_OTHERS = np.array([next(rest for rest in permutations(set(range(4)) - {i, j}) if _is_even((i, j) + rest))
                        for i, j in EDGE_PAIRS])


def _sorted_keys(rows: np.ndarray):
    """One stable sort of the rows (r, j) of vertex indices by their sorted vertices: ``order`` (r,) and the
    sorted keys (r,), equal for the rows that hold the same vertices."""
    rows = np.sort(rows, axis=1)
    keys = rows[:, 0].astype(np.int64)
    base = int(rows.max()) + 1 if rows.size else 1
    for column in range(1, rows.shape[1]):
        keys = keys * base + rows[:, column]
    order = np.argsort(keys, kind="stable")
    return order, keys[order]


def edge_rings(cells: np.ndarray, max_ring: int = MAX_RING, nodes: np.ndarray | None = None) -> dict:
    """The interior edges of a tetrahedral mesh with the cells around them in order; with ``nodes`` ((n,) bool),
    only the edges whose two ends are among them (the others are not sorted at all).

    Returns
    -------
    n -> (a, b, ring, around) for each ring size n in 3 .. ``max_ring``: the edges (a, b) (E,) whose cells close
    a ring of n; ``ring`` (E, n) the vertices x_0 .. x_{n-1} around the edge, ordered so that every cell
    (a, b, x_i, x_{i+1}) is positively oriented; ``around`` (E, n) the cell holding x_i and x_{i+1}.
    """
    a, b = cells[:, EDGE_PAIRS[:, 0]].ravel(), cells[:, EDGE_PAIRS[:, 1]].ravel()
    x, y = cells[:, EDGE_OTHERS[:, 0]].ravel(), cells[:, EDGE_OTHERS[:, 1]].ravel()
    swap = a > b  # (b, a, x, y) has the other orientation: the ring runs the other way
    a, b, x, y = np.where(swap, b, a), np.where(swap, a, b), np.where(swap, y, x), np.where(swap, x, y)
    owner = np.repeat(np.arange(len(cells)), len(EDGE_PAIRS))
    if nodes is not None:
        near = np.flatnonzero(nodes[a] & nodes[b])
        a, b, x, y, owner = a[near], b[near], x[near], y[near], owner[near]
    order, keys = _sorted_keys(np.stack([a, b], axis=1))
    start = np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1], [True]]))
    counts = np.diff(start)
    edges = np.stack([a[order[start[:-1]]], b[order[start[:-1]]]], axis=1)
    rings = {}
    for n in range(3, max_ring + 1):
        chosen = np.flatnonzero(counts == n)
        rows = order[start[chosen][:, None] + np.arange(n)]
        xs, ys, cell = x[rows], y[rows], owner[rows]
        every = np.arange(len(chosen))
        ring, around = np.empty_like(xs), np.empty_like(cell)
        ring[:, 0], around[:, 0], current = xs[:, 0], cell[:, 0], ys[:, 0]
        closed = np.ones(len(chosen), bool)  # an edge on the boundary has an open fan of cells
        for i in range(1, n):
            hit = xs == current[:, None]
            closed &= hit.sum(axis=1) == 1
            column = np.argmax(hit, axis=1)
            ring[:, i], around[:, i], current = current, cell[every, column], ys[every, column]
        closed &= current == ring[:, 0]
        rings[n] = (edges[chosen[closed], 0], edges[chosen[closed], 1], ring[closed], around[closed])
    return rings


def _ring_cells(a: np.ndarray, b: np.ndarray, ring: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(E, t, 2, 4): for each triangle (x, y, z) of the ring's polygon, the cells (x, y, z, b) and (x, z, y, a)
    that replace those around the edge (a, b)."""
    x, y, z = (ring[:, triangles[:, i]] for i in range(3))
    apex_b, apex_a = (np.broadcast_to(v[:, None], x.shape) for v in (b, a))
    return np.stack([np.stack([x, y, z, apex_b], axis=-1), np.stack([x, z, y, apex_a], axis=-1)], axis=2)


def _facet_pairs(cells: np.ndarray, nodes: np.ndarray | None):
    """The pairs of cells across an interior facet (with ``nodes``, (n,) bool: the facets whose vertices are all
    among them): cell_a, cell_b (p,), their far vertices a, b (p,) and the facet (p, k), oriented out of cell_a."""
    k = cells.shape[1] - 1
    facets = facets_of(cells).reshape(-1, k)
    rows = np.arange(len(facets)) if nodes is None else np.flatnonzero(nodes[facets].all(axis=1))
    order, keys = _sorted_keys(facets[rows])  # the rows that are the same facet, paired as by neighbour_pairs
    same = keys[1:] == keys[:-1]
    first, second = rows[order[:-1][same]], rows[order[1:][same]]
    cell_a, cell_b = first // (k + 1), second // (k + 1)
    return cell_a, cell_b, cells[cell_a, first % (k + 1)], cells[cell_b, second % (k + 1)], facets[first]


def _across(a: np.ndarray, b: np.ndarray, facet: np.ndarray) -> np.ndarray:
    """The cells that replace the two on ``facet`` (p, k) with far vertices a, b: (p, 3, 4) around the edge (a, b)
    in 3D (2-3 flip), (p, 2, 3) in 2D (2-2 flip)."""
    if facet.shape[1] == 3:
        return np.stack([np.stack([a, b, facet[:, i], facet[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1)
    return np.stack([np.stack([a, facet[:, 0], b], axis=1), np.stack([b, facet[:, 1], a], axis=1)], axis=1)


def _fresh_nodes(cells: np.ndarray, fresh: np.ndarray | None, n_points: int):
    """(n,) bool, the vertices of the ``fresh`` cells; None when every group is to be tested."""
    if fresh is None:
        return None
    nodes = np.zeros(n_points, bool)
    nodes[cells[fresh].ravel()] = True
    return nodes


def flip_candidates(points: np.ndarray, cells: np.ndarray, quality: np.ndarray, fresh: np.ndarray | None = None):
    """The flips that raise the worst radius ratio of the cells they replace by more than ``FLIP_GAIN``, among
    the groups of cells whose worst radius ratio is below ``FLIP_QUALITY``; with ``fresh`` ((m,) bool), only among
    the groups that hold a fresh cell.

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
    nodes = _fresh_nodes(cells, fresh, len(points))  # the groups to test have their edges and facets among them
    if k == 3:
        for n, (a, b, ring, around) in edge_rings(cells, nodes=nodes).items():
            worst_old = quality[around].min(axis=1)
            poor = worst_old < FLIP_QUALITY
            if fresh is not None:
                poor &= fresh[around].any(axis=1)
            a, b, ring, around, worst_old = a[poor], b[poor], ring[poor], around[poor], worst_old[poor]
            triangles, triangulations = RING_TRIANGULATIONS[n]
            new = _ring_cells(a, b, ring, triangles)
            worst = signed_radius_ratio(points, new.reshape(-1, 4)).reshape(new.shape[:3]).min(axis=2)
            by_triangulation = worst[:, triangulations].min(axis=2)  # (E, T)
            best = np.argmax(by_triangulation, axis=1) if len(a) else np.zeros(0, np.int64)
            gain = by_triangulation[np.arange(len(a)), best] - worst_old
            keep = gain > FLIP_GAIN
            chosen = new[np.flatnonzero(keep)[:, None], triangulations[best[keep]]].reshape(-1, 2 * (n - 2), 4)
            found.append((around[keep], chosen, gain[keep]))
    cell_a, cell_b, a, b, facet = _facet_pairs(cells, nodes)
    worst_old = np.minimum(quality[cell_a], quality[cell_b])
    poor = worst_old < FLIP_QUALITY
    if fresh is not None:
        poor &= fresh[cell_a] | fresh[cell_b]
    new = _across(a[poor], b[poor], facet[poor])
    gain = signed_radius_ratio(points, new.reshape(-1, k + 1)).reshape(new.shape[:2]).min(axis=1) - worst_old[poor]
    keep = gain > FLIP_GAIN
    found.append((np.stack([cell_a[poor], cell_b[poor]], axis=1)[keep], new[keep], gain[keep]))
    return found


def delaunay_candidates(points: np.ndarray, cells: np.ndarray, spheres: np.ndarray,
                        fresh: np.ndarray | None = None):
    """The flips towards the Delaunay triangulation of the domain: 2-3 flips (2-2 in 2D) of two cells whose shared
    facet is not locally Delaunay (the far vertex of one inside the other's circumsphere) and 3-2 flips of the
    three cells around an edge whose two replacements are; gain: how far inside, as a fraction of the squared
    circumradius, above ``DELAUNAY_GAIN``.  Every new cell must be positive (radius ratio above ``FLAT_QUALITY``).
    ``spheres``: (m, k + 1) the cells' circumcentres and radii (:func:`circumsphere_rows`); ``fresh`` as in
    :func:`flip_candidates`.

    Returns
    -------
    list of (old (c, j) cell indices, new (c, j', k + 1) cells, gain (c,)), one entry per kind of flip
    """
    k = points.shape[1]
    found = []
    nodes = _fresh_nodes(cells, fresh, len(points))
    if k == 3:
        a, b, ring, around = edge_rings(cells, 3, nodes)[3]
        if fresh is not None:
            tested = fresh[around].any(axis=1)
            a, b, ring, around = a[tested], b[tested], ring[tested], around[tested]
        new = _ring_cells(a, b, ring, RING_TRIANGULATIONS[3][0])[:, 0]   # (E, 2, 4)
        centre, radius = circumspheres(points, new[:, 0])
        found.append(_positive_flips(points, around, new, _beyond(points[a], centre, radius)))
    cell_a, cell_b, a, b, facet = _facet_pairs(cells, nodes)
    if fresh is not None:
        tested = fresh[cell_a] | fresh[cell_b]
        cell_a, cell_b, a, b, facet = cell_a[tested], cell_b[tested], a[tested], b[tested], facet[tested]
    gain = -_beyond(points[b], spheres[cell_a, :k], spheres[cell_a, k])
    found.append(_positive_flips(points, np.stack([cell_a, cell_b], axis=1), _across(a, b, facet), gain))
    return found


def _beyond(x: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(p,) (|x - centre|^2 - radius^2) / radius^2: above 0 outside the sphere; nan for a flat cell's."""
    offset = x - centre
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return (np.einsum("ij,ij->i", offset, offset) - radius ** 2) / radius ** 2


def _positive_flips(points: np.ndarray, old: np.ndarray, new: np.ndarray, gain: np.ndarray) -> tuple:
    """The flips (old, new, gain) whose gain is above ``DELAUNAY_GAIN`` and whose new cells are all positive.

    The gains are counted in whole steps of ``DELAUNAY_GAIN`` and a new cell must be above ``FLAT_QUALITY``: the
    biting's nodes lie almost on a lattice, where many spheres pass through five nodes and many cells through four
    to rounding, and rounding must not choose the flips (the same mesh with any floating-point library)."""
    with np.errstate(invalid="ignore"):
        gain = np.floor(gain / DELAUNAY_GAIN) * DELAUNAY_GAIN
    keep = gain > DELAUNAY_GAIN
    keep[keep] = signed_radius_ratio(points, new[keep].reshape(-1, new.shape[2])).reshape(
        -1, new.shape[1]).min(axis=1) > FLAT_QUALITY
    return old[keep], new[keep], gain[keep]


def circumsphere_rows(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, k + 1) each cell's circumcentre and circumradius in one row."""
    centre, radius = circumspheres(points, cells)
    return np.column_stack([centre, radius])


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
         progress: ProgressCallback = None, delaunay: bool = False) -> np.ndarray:
    """Apply improving flips (:func:`flip_candidates`), pass after pass, until none is left (at most ``passes``);
    with ``delaunay``, the flips towards the Delaunay triangulation instead (:func:`delaunay_candidates`).

    Flips replace cells inside the domain only: the boundary, the nodes and the volume stay as they are.

    Returns
    -------
    (m', k + 1) int64, the new cells, positively oriented
    """
    measure, candidates_of = ((circumsphere_rows, delaunay_candidates) if delaunay
                              else (signed_radius_ratio, flip_candidates))
    measured = measure(points, cells)
    fresh = None  # the first pass tests every group, each next one those with a cell the pass before made
    for pass_ in range(passes):
        candidates = candidates_of(points, cells, measured, fresh)
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
        cells = np.concatenate([cells[~removed]] + added)
        fresh = np.arange(len(cells)) >= len(cells) - sum(len(new) for new in added)
        measured = np.concatenate([measured[~removed]] + [measure(points, new) for new in added])
    return cells
