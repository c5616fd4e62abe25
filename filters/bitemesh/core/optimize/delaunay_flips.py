"""Flips towards the Delaunay triangulation of a domain, the relaxation's local update
(:func:`bitemesh.core.optimize.relax.relax`): Lawson's flips (2-3 and 3-2 in 3D, 2-2 in 2D), cell after cell from a
stack, with the cells' neighbours kept up to date, in a compiled kernel.

An interior facet is locally Delaunay when the far vertex of the cell on one side lies outside the circumsphere of
the cell on the other.  A facet that is not (by more than ``DELAUNAY_GAIN`` of the squared circumradius: far above
rounding, so that no flip and its inverse both pass) is flipped: 2-3 (2-2 in 2D) when the segment joining the two
far vertices crosses it, else 3-2 when an edge of the facet has exactly three cells around it.  Every new cell must
be positive, with a radius ratio above ``FLAT_QUALITY``: the biting's nodes lie almost on a lattice, where many
spheres pass through five nodes to rounding.  No flip makes an edge or a face that the mesh already holds
(:func:`_star_holds`): a relaxed mesh may fold at a thin wall, and such a flip leaves a facet in three cells.  Flips
replace cells inside the domain only: the boundary facets, the nodes and the volume stay.
"""
from __future__ import annotations

import numpy as np

from ..mesh.adjacency import cell_neighbours
from ..compiled import kernel
from ..mesh.simplicial import _circumsphere
from ..mesh.quality import _radius_ratios_2d, _radius_ratios_3d

#: a flip must take a vertex at least this fraction of the squared circumradius inside a circumsphere.
DELAUNAY_GAIN = 1e-6
#: a cell whose radius ratio is below FLAT_QUALITY counts as flat: no flip makes one, no move of the relaxation
#: either (rounding must not decide whether a cell is made).
FLAT_QUALITY = 1e-6
#: the flips of one call stop after this many per cell (Lawson's flips end in 2D, and in practice in 3D).
FLIPS_PER_CELL = 50


@kernel
def _inside(points: np.ndarray, x: int, sphere: np.ndarray) -> float:
    """How far point ``x`` lies inside the sphere (k + 1,) (centre, radius), as a fraction of its squared radius
    (<= 0: outside; -1 for a flat cell's)."""
    k = len(sphere) - 1
    radius = sphere[k]
    if not np.isfinite(radius) or radius <= 0.0:
        return -1.0
    squared = 0.0
    for i in range(k):
        d = points[x, i] - sphere[i]
        squared += d * d
    return (radius * radius - squared) / (radius * radius)


@kernel
def _all_positive(points: np.ndarray, new: np.ndarray) -> bool:
    """Whether every cell of ``new`` (c, k + 1) has a radius ratio above ``FLAT_QUALITY``."""
    ratios = _radius_ratios_3d(points, new) if new.shape[1] == 4 else _radius_ratios_2d(points, new)
    return ratios.min() > FLAT_QUALITY


@kernel
def _face(cells: np.ndarray, c: int, skip: int, out: np.ndarray) -> None:
    """``out`` (k,) := the sorted vertices of the facet of cell ``c`` opposite vertex ``skip``."""
    length = 0
    for j in range(cells.shape[1]):
        if j != skip:
            v, at = cells[c, j], length
            while at > 0 and out[at - 1] > v:
                out[at] = out[at - 1]
                at -= 1
            out[at] = v
            length += 1


@kernel
def _same(x: np.ndarray, y: np.ndarray) -> bool:
    for j in range(len(x)):
        if x[j] != y[j]:
            return False
    return True


@kernel
def _replace(cells, across, alive, free, n_free, n_cells, old, new):
    """Put the cells ``new`` (c, k + 1) in place of the cells ``old`` (o,) that fill the same region, linking each
    new facet to the cell outside across it (and back) or to the new cell that shares it.  Slots: the old ones,
    then freed ones, then the end.  Returns (slots of the new cells, n_free, n_cells)."""
    corners = cells.shape[1]
    outer = np.empty((len(old) * corners, corners - 1), np.int64)   # the facets towards the outside
    outer_cell = np.empty(len(old) * corners, np.int64)
    outer_back = np.empty(len(old) * corners, np.int64)   # their position in the outside cell, -1: boundary
    count = 0
    for o in old:
        for i in range(corners):
            d = across[o, i]
            if d >= 0:
                inside = False
                for p in old:
                    inside = inside or d == p
                if inside:
                    continue
            _face(cells, o, i, outer[count])
            outer_cell[count], outer_back[count] = d, -1
            if d >= 0:
                for j in range(corners):
                    if across[d, j] == o:
                        outer_back[count] = j
            count += 1
    slots = np.empty(len(new), np.int64)
    for s in range(len(new)):
        if s < len(old):
            slots[s] = old[s]
        elif n_free > 0:
            n_free -= 1
            slots[s] = free[n_free]
        else:
            slots[s], n_cells = n_cells, n_cells + 1
    for s in range(len(new), len(old)):
        alive[old[s]] = False
        free[n_free], n_free = old[s], n_free + 1
    for s in range(len(new)):
        cells[slots[s]] = new[s]
        alive[slots[s]] = True
    mine = np.empty(corners - 1, np.int64)
    theirs = np.empty(corners - 1, np.int64)
    for s in range(len(new)):
        for i in range(corners):
            _face(cells, slots[s], i, mine)
            linked = False
            for f in range(count):
                if _same(outer[f], mine):
                    across[slots[s], i] = outer_cell[f]
                    if outer_back[f] >= 0:
                        across[outer_cell[f], outer_back[f]] = slots[s]
                    linked = True
            for t in range(len(new)):
                if t != s and not linked:
                    for j in range(corners):
                        _face(cells, slots[t], j, theirs)
                        if _same(theirs, mine):
                            across[slots[s], i] = slots[t]
    return slots, n_free, n_cells


@kernel
def _even_rest(cell: np.ndarray, u: int, v: int):
    """The other two vertices (x, y) of tetrahedron ``cell`` ordered so that (u, v, x, y) is an even permutation of
    it (as positively oriented)."""
    order = np.empty(4, np.int64)
    order[0], order[1] = -1, -1
    rest = 2
    for j in range(4):
        if cell[j] == u:
            order[0] = j
        elif cell[j] == v:
            order[1] = j
        else:
            order[rest], rest = j, rest + 1
    inversions = 0
    for i in range(4):
        for j in range(i + 1, 4):
            inversions += order[i] > order[j]
    x, y = cell[order[2]], cell[order[3]]
    return (x, y) if inversions % 2 == 0 else (y, x)


@kernel
def _position(cells: np.ndarray, c: int, v: int) -> int:
    for j in range(cells.shape[1]):
        if cells[c, j] == v:
            return j
    return -1


@kernel
def _pair(c: int, d: int) -> np.ndarray:
    pair = np.empty(2, np.int64)
    pair[0], pair[1] = c, d
    return pair


#: the cells around a vertex that :func:`_star_holds` walks, at most (it answers True beyond: no flip is made).
MAX_STAR = 256


@kernel
def _star_holds(cells: np.ndarray, across: np.ndarray, start: int, v: int, p: int, q: int) -> bool:
    """Whether a cell around vertex ``v`` (those reached from cell ``start``, which holds v, across facets that
    hold v) holds ``p`` and, unless q < 0, ``q``: whether the edge (v, p) or the face (v, p, q) is already in the
    mesh.  A flip must not make it again: on a mesh folded at a wall a few cells thick, one can pass the flip's own
    tests and leave a facet in three cells."""
    star = np.empty(MAX_STAR, np.int64)
    star[0], count, seen = start, 1, 0
    while seen < count:
        c = star[seen]
        seen += 1
        has_p, has_q = False, q < 0
        for j in range(cells.shape[1]):
            has_p = has_p or cells[c, j] == p
            has_q = has_q or cells[c, j] == q
        if has_p and has_q:
            return True
        for j in range(cells.shape[1]):
            d = across[c, j]
            if d < 0 or cells[c, j] == v:   # beyond the boundary, or across the facet without v
                continue
            known = False
            for i in range(count):
                known = known or star[i] == d
            if not known:
                if count == MAX_STAR:
                    return True
                star[count], count = d, count + 1
    return False


@kernel
def _flip_facet(points, cells, across, c, i, sphere):
    """The flip of the facet of cell ``c`` (circumsphere ``sphere``) opposite its vertex ``i``, if that facet is not
    locally Delaunay and a flip makes positive cells: (old (o,), new (c', k + 1)); empty arrays when none."""
    corners = cells.shape[1]
    none = (np.empty(0, np.int64), np.empty((0, corners), np.int64))
    d = across[c, i]
    if d < 0:
        return none
    a, b = cells[c, i], cells[d, _position(across, d, c)]
    if _inside(points, b, sphere) <= DELAUNAY_GAIN:
        return none
    facet = np.empty(corners - 1, np.int64)   # oriented out of c
    length = 0
    for j in range(corners):
        if j != i:
            facet[length], length = cells[c, j], length + 1
    if i % 2 == 1 and corners == 4:
        facet[1], facet[2] = facet[2], facet[1]
    if corners == 3:
        if i % 2 == 1:
            facet[0], facet[1] = facet[1], facet[0]
        new = np.empty((2, 3), np.int64)
        new[0, 0], new[0, 1], new[0, 2], new[1, 0], new[1, 1], new[1, 2] = a, facet[0], b, b, facet[1], a
        if not _all_positive(points, new) or _star_holds(cells, across, c, a, b, -1):
            return none
        return _pair(c, d), new
    new = np.empty((3, 4), np.int64)
    for j in range(3):
        new[j, 0], new[j, 1], new[j, 2], new[j, 3] = a, b, facet[j], facet[(j + 1) % 3]
    if _all_positive(points, new) and not _star_holds(cells, across, c, a, b, -1):
        return _pair(c, d), new
    for j in range(3):   # 3-2: the edge (u, v) of the facet, if three cells (c, d, e) are around it
        u, v, w = facet[j], facet[(j + 1) % 3], facet[(j + 2) % 3]
        e = across[c, _position(cells, c, w)]
        if e < 0 or e != across[d, _position(cells, d, w)]:
            continue
        x, y = _even_rest(cells[c], u, v)   # the ring around (u, v): x, y, then b
        two = np.empty((2, 4), np.int64)
        two[0, 0], two[0, 1], two[0, 2], two[0, 3], two[1, 0], two[1, 1], two[1, 2], two[1, 3] = x, y, b, v, x, b, y, u
        if _all_positive(points, two) and not _star_holds(cells, across, c, x, y, b):
            three = np.empty(3, np.int64)
            three[0], three[1], three[2] = c, d, e
            return three, two
    return none


@kernel
def _lawson(points, cells, across, alive, n_cells, max_flips):
    """Flip the facets that are not locally Delaunay, from a stack of the cells to check (all of them first, then
    the new ones), at most ``max_flips`` times.  ``cells``, ``across`` (capacity, k + 1) and ``alive``
    (capacity,) hold ``n_cells`` cells in their first rows and are changed in place, in room for ``capacity``
    cells; it stops early when the room is full.  Returns (n_cells, flips made)."""
    capacity, corners = cells.shape
    free = np.empty(capacity, np.int64)
    stack = np.empty(capacity, np.int64)
    queued = np.zeros(capacity, np.bool_)
    for c in range(n_cells):
        stack[c], queued[c] = n_cells - 1 - c, True   # cell 0 on top
    top, n_free, flips = n_cells, 0, 0
    sphere = np.empty(corners)
    while top > 0 and flips < max_flips and (n_free > 0 or n_cells < capacity):
        top -= 1
        c = stack[top]
        queued[c] = False
        if not alive[c]:
            continue
        _circumsphere(points, cells[c], sphere)
        for i in range(corners):
            old, new = _flip_facet(points, cells, across, c, i, sphere)
            if len(old) == 0:
                continue
            slots, n_free, n_cells = _replace(cells, across, alive, free, n_free, n_cells, old, new)
            flips += 1
            for s in slots:
                if not queued[s]:
                    stack[top], top, queued[s] = s, top + 1, True
            break
    return n_cells, flips


def flip_to_delaunay(points: np.ndarray, cells: np.ndarray, across: np.ndarray | None = None):
    """Flip the interior facets of a valid mesh until each is locally Delaunay (see the module's docstring).

    Parameters
    ----------
    points : (n, k) float64, k = 2 or 3
    cells : (m, k + 1) int64, positively oriented
    across : (m, k + 1) int64, :func:`~bitemesh.core.mesh.adjacency.cell_neighbours` of ``cells`` if known

    Returns
    -------
    cells : (m', k + 1) int64, the new cells, positively oriented: the same boundary facets, nodes and volume
    across : (m', k + 1) int64, their neighbours (as :func:`~bitemesh.core.mesh.adjacency.cell_neighbours`)
    """
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    if len(cells) == 0:
        return cells, np.zeros_like(cells)
    across = cell_neighbours(cells) if across is None else np.ascontiguousarray(across, dtype=np.int64)
    points = np.ascontiguousarray(points, dtype=np.float64)
    budget = FLIPS_PER_CELL * len(cells)
    while True:   # again, with more room, when a run filled its room (2-3 flips add a cell each)
        cells, across, full, flips = _flip_in_room(points, cells, across, len(cells) + len(cells) // 4 + 16, budget)
        budget -= flips
        if not full or budget <= 0:
            return cells, across


def _flip_in_room(points: np.ndarray, cells: np.ndarray, across: np.ndarray, capacity: int, budget: int):
    """:func:`_lawson` in room for ``capacity`` cells: (cells, across) compacted, whether the room filled, flips."""
    m, corners = cells.shape
    room = np.empty((capacity, corners), np.int64)
    room[:m] = cells
    links = np.full((capacity, corners), -1, np.int64)
    links[:m] = across
    alive = np.zeros(capacity, bool)
    alive[:m] = True
    n_cells, flips = _lawson(points, room, links, alive, m, budget)
    kept = np.flatnonzero(alive[:n_cells])
    index = np.cumsum(alive[:n_cells]) - 1   # the slots of the living cells, compacted
    links = links[kept]
    return room[kept], np.where(links >= 0, index[np.maximum(links, 0)], links), len(kept) == capacity, flips
