"""Which cells of a simplicial mesh touch: the cell across each facet, the pairs of cells on interior facets and
the rings of cells around interior edges, in compiled kernels (linear time, no sorting).

The flips (:mod:`bitemesh.core.optimize.flips`) find their candidates here on every pass;
:mod:`bitemesh.core.mesh.topology` finds the boundary facets.
"""
from __future__ import annotations

from itertools import combinations, permutations

import numpy as np

from ..compiled import kernel
from ..errors import InvalidInputError
from .simplicial import facet_corners, facet_of

#: the neighbour recorded for a facet held by its cell alone (on the boundary), and by three cells or more.
BOUNDARY, NON_MANIFOLD = -1, -2


def _is_even(permutation) -> bool:
    return sum(a > b for a, b in combinations(permutation, 2)) % 2 == 0


#: for each edge (i, j) of a tetrahedron, the other two vertices (k, l) ordered so that (i, j, k, l) is an even
#: permutation of (0, 1, 2, 3): then (v_i, v_j, v_k, v_l) is as positively oriented as (v_0, v_1, v_2, v_3).
EDGE_PAIRS = np.array(list(combinations(range(4), 2)))
EDGE_OTHERS = np.array([next(rest for rest in permutations(set(range(4)) - {i, j}) if _is_even((i, j) + rest))
                        for i, j in EDGE_PAIRS])


#: a cell of a k-D mesh (k >= 4) has facets of k vertices, keyed by their sorted indices of this many bits each.
KEY_BITS = 21


@kernel
def _facet_key(cells: np.ndarray, c: int, skip: int):
    """The facet of cell c opposite its vertex ``skip`` by its sorted vertices, in two words: the lowest, then
    (triangles) the middle one times 2^32 plus the highest, or (edges) the highest; a facet of 4 or 5 vertices
    (4-D, 5-D) packs them :data:`KEY_BITS` bits each, three in the first word."""
    if cells.shape[1] > 4:
        ids = np.empty(cells.shape[1] - 1, np.int64)
        n = 0
        for j in range(cells.shape[1]):   # inserted in order: numba's sort compiles for 1 s
            if j != skip:
                at = n
                while at > 0 and ids[at - 1] > cells[c, j]:
                    ids[at] = ids[at - 1]
                    at -= 1
                ids[at] = cells[c, j]
                n += 1
        rest = np.int64(0)
        for j in range(3, n):
            rest = (rest << KEY_BITS) | ids[j]
        return (((ids[0] << KEY_BITS) | ids[1]) << KEY_BITS) | ids[2], rest
    low, high, total = np.int64(1 << 62), np.int64(-1), np.int64(0)
    for j in range(cells.shape[1]):
        if j != skip:
            v = cells[c, j]
            total += v
            low, high = min(low, v), max(high, v)
    return low, ((total - low - high) << 32) + high if cells.shape[1] == 4 else high


@kernel
def _neighbours(cells: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """(m, k + 1) int64, see :func:`cell_neighbours`: each facet row (c (k + 1) + i) keyed once by
    :func:`_facet_key`, then looked up in an open-addressing hash table (multiplicative hashing, linear probing) of
    ``slots`` (a power of two, -1: empty), each holding the first facet row that has its key; the second is the cell
    across it."""
    m, corners = cells.shape
    size, bits = len(slots), 0
    while (1 << bits) < size:
        bits += 1
    lows, rests = np.empty(m * corners, np.int64), np.empty(m * corners, np.int64)
    for c in range(m):
        for skip in range(corners):
            lows[c * corners + skip], rests[c * corners + skip] = _facet_key(cells, c, skip)
    across = np.full((m, corners), BOUNDARY, np.int64)
    for row in range(m * corners):
        c, skip, low, rest = row // corners, row % corners, lows[row], rests[row]
        mixed = (low * np.int64(-7046029254386353131) + rest) * np.int64(-7046029254386353131)   # wraps
        slot = np.int64(np.uint64(mixed) >> np.uint64(64 - bits))
        first = np.int64(slots[slot])
        while first >= 0 and (lows[first] != low or rests[first] != rest):
            slot = (slot + 1) & (size - 1)
            first = np.int64(slots[slot])
        if first < 0:
            slots[slot] = row
            continue
        first_cell, first_skip = first // corners, first % corners
        second = across[first_cell, first_skip]
        if second == BOUNDARY:
            across[c, skip], across[first_cell, first_skip] = first_cell, c
            continue
        for j in range(corners if second >= 0 else 0):   # a third cell on this facet: the second's row too
            other = second * corners + j
            if across[second, j] == first_cell and other != first and lows[other] == low and rests[other] == rest:
                across[second, j] = NON_MANIFOLD
                break
        across[c, skip] = across[first_cell, first_skip] = NON_MANIFOLD
    return across


def cell_neighbours(cells: np.ndarray) -> np.ndarray:
    """(m, k + 1) int64, the cell across the facet opposite vertex i of cell c; ``BOUNDARY`` (-1) where that facet
    is held by cell c alone, ``NON_MANIFOLD`` (-2) where by three cells or more."""
    if len(cells) == 0:
        return np.zeros((0, cells.shape[1]), np.int64)
    if cells.shape[1] > 4 and cells.max() >= 1 << KEY_BITS:
        raise InvalidInputError(f"a mesh of {cells.shape[1] - 1}-D cells may hold at most {1 << KEY_BITS} points "
                                f"(its facets are keyed by {KEY_BITS}-bit indices), got {int(cells.max()) + 1}; "
                                "mesh it coarser (a larger radius)")
    rows = cells.size
    size = 1 << max(1, (rows - 1).bit_length())   # at least one slot per facet row: at most half full inside
    return _neighbours(np.ascontiguousarray(cells, dtype=np.int64),
                       np.full(size, -1, np.int32 if rows < 2**31 else np.int64))


@kernel
def _facet_parity(cells: np.ndarray, c: int, facet: np.ndarray) -> int:
    """0 or 1: the parity of the inversions of cell c's vertices at the positions ``facet`` (a row of
    :func:`~bitemesh.core.mesh.simplicial.facet_corners`, the facet as :func:`~bitemesh.core.mesh.simplicial.facet_of`
    orders it)."""
    parity = 0
    for i in range(len(facet)):
        for j in range(i + 1, len(facet)):
            if cells[c, facet[i]] > cells[c, facet[j]]:
                parity += 1
    return parity % 2


@kernel
def _same_side(cells: np.ndarray, across: np.ndarray, facets: np.ndarray):
    corners = cells.shape[1]
    count, first, second = 0, -1, -1
    for c in range(len(cells)):
        for i in range(corners):
            d = across[c, i]
            if d < c:
                continue
            key = _facet_key(cells, c, i)
            for j in range(corners):
                if across[d, j] == c and d * corners + j > c * corners + i and _facet_key(cells, d, j) == key:
                    if _facet_parity(cells, c, facets[i]) == _facet_parity(cells, d, facets[j]):
                        count += 1
                        if first < 0:
                            first, second = c, d
                    break
    return count, first, second


def same_side_pairs(cells: np.ndarray, across: np.ndarray):
    """The interior facets whose two cells lie on the same side of them (overlapping cells): both cells orient the
    facet alike, where a consistently oriented mesh has them opposite.  ``across``: :func:`cell_neighbours`.

    Returns
    -------
    count : int; first : (int, int) the two cells of the first such facet in cell order, (-1, -1) if none
    """
    count, first, second = _same_side(np.ascontiguousarray(cells, dtype=np.int64), across,
                                      facet_corners(cells.shape[1]))
    return int(count), (int(first), int(second))


def facet_pairs(cells: np.ndarray, across: np.ndarray, start: np.ndarray | None = None,
                wanted: np.ndarray | None = None):
    """The pairs of cells on an interior facet (with ``start``, (m,) bool: those with a start cell among them; with
    ``wanted``, (m,) bool: those with a wanted cell among them), in the order of the first cell and its facet:
    cell_a < cell_b (p,), their far vertices a, b (p,) and the facet (p, k), oriented out of cell_a.  ``across``:
    :func:`cell_neighbours` of ``cells``."""
    upper = across > np.arange(len(cells))[:, None]
    for among in (start, wanted):
        if among is not None:
            upper &= among[:, None] | among[np.maximum(across, 0)]
    cell_a, opposite = np.nonzero(upper)
    cell_b = across[cell_a, opposite]
    far = np.argmax(across[cell_b] == cell_a[:, None], axis=1)
    facet = facet_of(cells, cell_a, opposite)
    return cell_a, cell_b, cells[cell_a, opposite], cells[cell_b, far], facet


@kernel
def _rings(cells: np.ndarray, across: np.ndarray, start: np.ndarray, wanted: np.ndarray, max_ring: int,
           pairs: np.ndarray, others: np.ndarray):
    """The closed rings of 3 .. ``max_ring`` cells around the edges of the start cells, each once (walked from its
    first start cell), that hold a wanted cell; see :func:`edge_rings`.  Returns (E,) sizes, a, b and
    (E, max_ring) ring, around."""
    m = len(cells)
    sizes = np.zeros(6 * m, np.int64)
    ends = np.empty((6 * m, 2), np.int64)
    ring = np.empty((6 * m, max_ring), np.int64)
    around = np.empty((6 * m, max_ring), np.int64)
    found = 0
    for c in range(m):
        if not start[c]:
            continue
        for e in range(6):
            a, b = cells[c, pairs[e, 0]], cells[c, pairs[e, 1]]
            x, y = cells[c, others[e, 0]], cells[c, others[e, 1]]
            if a > b:   # (b, a, y, x) is as positively oriented as (a, b, x, y)
                a, b, x, y = b, a, y, x
            ring[found, 0], around[found, 0] = x, c
            cell, dropped, current, n, closed = c, x, y, 1, False
            while True:
                position = 0
                while cells[cell, position] != dropped:
                    position += 1
                cell = across[cell, position]   # the cell on the facet (a, b, current)
                if cell < 0:
                    break
                if cell == c:
                    closed = True
                    break
                if cell < c and start[cell] or n == max_ring:   # walked from an earlier start cell, or too long
                    break
                following = -1
                for j in range(4):
                    v = cells[cell, j]
                    if v != a and v != b and v != current:
                        following = v
                ring[found, n], around[found, n] = current, cell
                dropped, current, n = current, following, n + 1
            held = False
            for i in range(n if closed else 0):
                held = held or wanted[around[found, i]]
            if held and n >= 3:
                sizes[found], ends[found, 0], ends[found, 1] = n, a, b
                found += 1
    return sizes[:found], ends[:found, 0], ends[:found, 1], ring[:found], around[:found]


def edge_rings(cells: np.ndarray, across: np.ndarray, max_ring: int, start: np.ndarray | None = None,
               wanted: np.ndarray | None = None) -> dict:
    """The interior edges of a tetrahedral mesh with the cells around them in order (with ``start``, (m,) bool:
    the edges with a start cell around them), in the order of their first (start) cell and its edges; with
    ``wanted`` ((m,) bool), only those with a wanted cell around them, in the same order.
    ``across``: :func:`cell_neighbours` of ``cells``.

    Returns
    -------
    n -> (a, b, ring, around) for each ring size n in 3 .. ``max_ring``: the edges (a, b) (E,), a < b, whose cells
    close a ring of n; ``ring`` (E, n) the vertices x_0 .. x_{n-1} around the edge, ordered so that every cell
    (a, b, x_i, x_{i+1}) is positively oriented; ``around`` (E, n) the cell holding x_i and x_{i+1}.
    """
    start = np.ones(len(cells), bool) if start is None else start
    wanted = np.ones(len(cells), bool) if wanted is None else wanted
    sizes, a, b, ring, around = _rings(np.ascontiguousarray(cells, dtype=np.int64), across, start, wanted, max_ring,
                                       EDGE_PAIRS, EDGE_OTHERS)
    return {n: (a[sizes == n], b[sizes == n], ring[sizes == n, :n], around[sizes == n, :n])
            for n in range(3, max_ring + 1)}


def replaced(cells: np.ndarray, across: np.ndarray, removed: np.ndarray, added: np.ndarray):
    """The cells with ``removed`` ((m,) bool) taken out and ``added`` ((a, k + 1)) put at the end, and their
    neighbours: ``across`` (:func:`cell_neighbours` of ``cells``) renumbered, and the facets of the added cells and
    those that faced a removed cell matched among themselves (few: sorted, not hashed).

    Returns
    -------
    cells : (m - removed + a, k + 1) int64, ``concatenate([cells[~removed], added])``
    across : its :func:`cell_neighbours`, when the added cells fill exactly the removed ones' place
    """
    unknown = -3
    index = np.cumsum(~removed) - 1
    index[removed] = unknown
    kept = across[~removed]
    kept = np.where(kept >= 0, index[np.maximum(kept, 0)], kept)
    cells = np.concatenate([cells[~removed], added])
    across = np.concatenate([kept, np.full(added.shape, unknown, np.int64)])
    rows = np.flatnonzero(across.ravel() == unknown)
    corners = cells.shape[1]
    facets = np.sort(facet_of(cells, rows // corners, rows % corners), axis=1)
    order = np.lexsort(facets.T[::-1])
    facets, rows = facets[order], rows[order]
    start = np.flatnonzero(np.concatenate([[True], np.any(facets[1:] != facets[:-1], axis=1), [True]]))
    sizes = np.diff(start)
    flat = across.ravel()
    flat[rows[start[:-1][sizes == 1]]] = BOUNDARY
    pair = start[:-1][sizes == 2]
    flat[rows[pair]], flat[rows[pair + 1]] = rows[pair + 1] // corners, rows[pair] // corners
    flat[rows[np.repeat(sizes, sizes) > 2]] = NON_MANIFOLD
    return cells, across
