"""Compiled kernels of the grid I (:mod:`bitemesh.core.grid.sampled`): f at a node, its multilinear interpolation and
that of its central-difference gradient, from either storage.

Every kernel sees the grid as three dimensional (a 2D grid has a last axis of one node) and its storage as
``(coarse, slots, bricks)``: the nodes are cut into bricks of 2 ** BRICK_SHIFT nodes a side; brick ``b`` holds its f
exactly in ``bricks[slots[b]]``, and where ``slots[b] < 0`` f is the multilinear refinement of ``coarse``, a grid
twice as coarse (node 2 i of the grid is node i of ``coarse``).  A dense grid is one brick, ``slots == [[[0]]]``.
"""
from __future__ import annotations

import numpy as np

from numba import njit, prange

from ..compiled import kernel

#: the bricks of a banded grid have 2 ** BRICK_SHIFT nodes a side (a 2D grid's: one along its last axis)
BRICK_SHIFT = 3
_MASK = (1 << BRICK_SHIFT) - 1
#: helpers compiled into the kernels that call them (numba inlines them: a call per node costs more than the read);
#: the small arithmetic ones are plain ``njit``, which LLVM inlines as well: numba's own inlining retypes the caller
#: at each site, and numba 0.56 (Debian's, beside its ParaView) took 275 s to compile these kernels with every helper
#: inlined that way, 44 s now (numba 0.68: 23 s -> 20 s for the whole demo; the meshes and their times unchanged)
inline = njit(inline="always")


@inline
def _refined_0(coarse, x, cy, cz):
    """f at fine x, coarse y and z: node x / 2 of coarse, or the mean of its two neighbours along axis 0."""
    low = coarse[x // 2, cy, cz]
    return low if x % 2 == 0 else 0.5 * (low + coarse[x // 2 + 1, cy, cz])


@inline
def _refined_1(coarse, x, y, cz):
    """f at fine x and y, coarse z: :func:`_refined_0` refined along axis 1."""
    low = _refined_0(coarse, x, y // 2, cz)
    return low if y % 2 == 0 else 0.5 * (low + _refined_0(coarse, x, y // 2 + 1, cz))


@inline
def refined_value(coarse, x, y, z):
    """f at node (x, y, z) of the grid with every cell of ``coarse`` halved, refined along axis 0, then 1, then 2,
    each new node the mean of its two neighbours (the arithmetic of refining the whole array axis after axis)."""
    low = _refined_1(coarse, x, y, z // 2)
    return low if z % 2 == 0 else 0.5 * (low + _refined_1(coarse, x, y, z // 2 + 1))


@inline
def node_value(coarse, slots, bricks, x, y, z):
    """f at node (x, y, z)."""
    if slots.size == 1:   # a dense grid
        return bricks[0, x, y, z]
    slot = slots[x >> BRICK_SHIFT, y >> BRICK_SHIFT, z >> BRICK_SHIFT]
    if slot >= 0:
        return bricks[slot, x & _MASK, y & _MASK, z & _MASK]
    return _far_refined(coarse, x, y, z)


@kernel
def _far_refined(coarse, x, y, z):
    """:func:`refined_value` called, not inlined: the callers' loops stay short (inlined, 5x slower)."""
    return refined_value(coarse, x, y, z)


@inline
def _difference(coarse, slots, bricks, shape, x, y, z, axis, step):
    """The derivative of f along ``axis`` at node (x, y, z) as numpy.gradient takes it: central inside, one-sided
    (first order) at the first and the last node."""
    at = x if axis == 0 else y if axis == 1 else z
    ahead, behind = int(at < shape[axis] - 1), int(at > 0)
    dx, dy, dz = int(axis == 0), int(axis == 1), int(axis == 2)
    return _derivative(node_value(coarse, slots, bricks, x + ahead * dx, y + ahead * dy, z + ahead * dz),
                       node_value(coarse, slots, bricks, x - behind * dx, y - behind * dy, z - behind * dz),
                       ahead, behind, step)


@njit
def _derivative(f_ahead, f_behind, ahead, behind, step):
    """numpy.gradient's difference of f at the node ``ahead`` (0 or 1) after and ``behind`` before one: central
    when both are 1, else one-sided."""
    difference = f_ahead - f_behind
    return difference / (2.0 * step) if ahead and behind else difference / step


@kernel
def _far_difference(coarse, slots, bricks, shape, x, y, z, axis, step):
    """:func:`_difference` called, not inlined: the rare path of :func:`interpolate_gradient` stays out of its loop
    (inlined, it makes the loop 5x slower)."""
    return _difference(coarse, slots, bricks, shape, x, y, z, axis, step)


@njit
def _axis(cc, n):
    """The lower and upper node along one axis at fractional node index ``cc`` of ``n`` nodes, and their weights
    1 - t and 1 - (1 - t); beyond the grid its nearest node (scipy's mode "nearest")."""
    start = np.floor(cc)
    node = int(min(max(start, -1.0), n - 1.0))
    weight = 1.0 - (cc - start)
    return min(max(node, 0), n - 1), min(max(node + 1, 0), n - 1), weight, 1.0 - weight


@inline
def _cell(points, p, origin, spacing, shape):
    """The grid cell around point p of the (m, k) ``points``: (is the point a number, x0, x1, y0, y1, z0, z1,
    and the weights a0, a1, b0, b1, c0, c1 of :func:`_axis`); a 2D grid's z is node 0 with weights 1 and 0."""
    cx = (points[p, 0] - origin[0]) / spacing[0]
    cy = (points[p, 1] - origin[1]) / spacing[1]
    cz = (points[p, 2] - origin[2]) / spacing[2] if points.shape[1] == 3 else 0.0
    x0, x1, a0, a1 = _axis(cx, shape[0])
    y0, y1, b0, b1 = _axis(cy, shape[1])
    z0, z1, c0, c1 = _axis(cz, shape[2])
    return cx == cx and cy == cy and cz == cz, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1


@njit
def _brick_of(slots, x0, x1, y0, y1, z0, z1):
    """(slot, its first node x, y, z) of the one brick that holds the cell's eight corners: -1 for one the coarse
    grid's refinement holds, -2 when the corners lie in several bricks; a dense grid's one brick from node 0."""
    if slots.size == 1:
        return 0, 0, 0, 0
    if (x0 >> BRICK_SHIFT == x1 >> BRICK_SHIFT and y0 >> BRICK_SHIFT == y1 >> BRICK_SHIFT
            and z0 >> BRICK_SHIFT == z1 >> BRICK_SHIFT):
        return slots[x0 >> BRICK_SHIFT, y0 >> BRICK_SHIFT, z0 >> BRICK_SHIFT], x0 & ~_MASK, y0 & ~_MASK, z0 & ~_MASK
    return -2, 0, 0, 0


@njit
def _mix(v000, v001, v010, v011, v100, v101, v110, v111, a0, a1, b0, b1, c0, c1):
    """The multilinear mean of a cell's corner values: summed in C order, each value times its weights in axis
    order (scipy's ``map_coordinates`` order 1)."""
    total = 0.0
    total += v000 * a0 * b0 * c0
    total += v001 * a0 * b0 * c1
    total += v010 * a0 * b1 * c0
    total += v011 * a0 * b1 * c1
    total += v100 * a1 * b0 * c0
    total += v101 * a1 * b0 * c1
    total += v110 * a1 * b1 * c0
    total += v111 * a1 * b1 * c1
    return total


@inline
def _value(coarse, slots, bricks, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1):
    """f multilinear in the cell of :func:`_cell`: its corners read from one brick where they lie in one."""
    slot, bx, by, bz = _brick_of(slots, x0, x1, y0, y1, z0, z1)
    if slot >= 0:
        f = bricks[slot]
        x0, x1, y0, y1, z0, z1 = x0 - bx, x1 - bx, y0 - by, y1 - by, z0 - bz, z1 - bz
        return _mix(f[x0, y0, z0], f[x0, y0, z1], f[x0, y1, z0], f[x0, y1, z1], f[x1, y0, z0], f[x1, y0, z1],
                    f[x1, y1, z0], f[x1, y1, z1], a0, a1, b0, b1, c0, c1)
    total = 0.0   # _mix's sum, corner by corner in the same order (one inlined read, not eight)
    for corner in range(8):
        i, j, h = corner >> 2, (corner >> 1) & 1, corner & 1
        x, y, z = x1 if i else x0, y1 if j else y0, z1 if h else z0
        value = _far_refined(coarse, x, y, z) if slot == -1 else node_value(coarse, slots, bricks, x, y, z)
        total += value * (a1 if i else a0) * (b1 if j else b0) * (c1 if h else c0)
    return total


@inline
def _node_gradient(coarse, slots, bricks, gradients, shape, spacing, x, y, z, q):
    """Component q of the central-difference gradient at node (x, y, z): kept in the bricks kept, else from the
    neighbours."""
    if slots.size == 1:
        return gradients[0, x, y, z, q]
    slot = slots[x >> BRICK_SHIFT, y >> BRICK_SHIFT, z >> BRICK_SHIFT]
    if slot < 0:
        return _far_difference(coarse, slots, bricks, shape, x, y, z, q, spacing[q])
    return gradients[slot, x & _MASK, y & _MASK, z & _MASK, q]


@inline
def _gradient(coarse, slots, bricks, gradients, shape, spacing, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1,
              q):
    """Component q of the central-difference gradient multilinear in the cell of :func:`_cell`."""
    slot, bx, by, bz = _brick_of(slots, x0, x1, y0, y1, z0, z1)
    if slot >= 0:
        g = gradients[slot]
        x0, x1, y0, y1, z0, z1 = x0 - bx, x1 - bx, y0 - by, y1 - by, z0 - bz, z1 - bz
        return _mix(g[x0, y0, z0, q], g[x0, y0, z1, q], g[x0, y1, z0, q], g[x0, y1, z1, q], g[x1, y0, z0, q],
                    g[x1, y0, z1, q], g[x1, y1, z0, q], g[x1, y1, z1, q], a0, a1, b0, b1, c0, c1)
    total = 0.0   # as in _value
    for corner in range(8):
        i, j, h = corner >> 2, (corner >> 1) & 1, corner & 1
        total += (_node_gradient(coarse, slots, bricks, gradients, shape, spacing, x1 if i else x0,
                                 y1 if j else y0, z1 if h else z0, q)
                  * (a1 if i else a0) * (b1 if j else b0) * (c1 if h else c0))
    return total


@kernel(parallel=True)
def evaluate_at(coarse, slots, bricks, shape, origin, spacing, points):
    """(m,) f multilinear at the (m, k) ``points`` of the grid of ``shape`` (3,) from ``origin`` (k,) by ``spacing``
    (k,) (the arithmetic of ``scipy.ndimage.map_coordinates(values, index.T, order=1, mode="nearest")``, scipy
    1.17, bit for bit); beyond the grid at most minus the distance to it; NaN at a NaN point."""
    out = np.empty(len(points))
    for p in prange(len(points)):
        number, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1 = _cell(points, p, origin, spacing, shape)
        if not number:
            out[p] = np.nan
            continue
        value = _value(coarse, slots, bricks, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1)
        squared = 0.0
        for d in range(points.shape[1]):
            beyond = (max(origin[d] - points[p, d], 0.0)
                      + max(points[p, d] - (origin[d] + (shape[d] - 1) * spacing[d]), 0.0))
            squared += beyond * beyond
        out[p] = min(value, -np.sqrt(squared)) if squared > 0 else value
    return out


@kernel(parallel=True)
def gradient_at(coarse, slots, bricks, gradients, shape, origin, spacing, points):
    """(m, k) the central-difference gradient of f (``numpy.gradient(values, *spacing)``) multilinear at the (m, k)
    ``points``, as :func:`evaluate_at` takes f; ``gradients`` is :func:`brick_gradients`."""
    m, k = points.shape
    out = np.empty((m, k))
    for p in prange(m):
        number, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1 = _cell(points, p, origin, spacing, shape)
        for q in range(k):
            out[p, q] = _gradient(coarse, slots, bricks, gradients, shape, spacing, x0, x1, y0, y1, z0, z1,
                                  a0, a1, b0, b1, c0, c1, q) if number else np.nan
    return out


@kernel(parallel=True)
def newton_to_surface(coarse, slots, bricks, gradients, shape, origin, spacing, points, steps, settled):
    """(m, k) points moved onto f = 0 by up to ``steps`` Newton steps along the interpolated gradient (as
    :func:`evaluate_at` and :func:`gradient_at` take f and grad f), each at most the largest spacing
    long; beyond the grid f is at most minus the distance to it.  A point stops once a step is shorter than
    ``settled`` (its next ones would be shorter still); a NaN point stays NaN."""
    m, k = points.shape
    out = points.copy()
    rows = np.zeros((m, k))   # the gradient at each point: the iterations share nothing
    limit = spacing.max()
    for p in prange(m):
        gradient = rows[p]
        for _ in range(steps):
            beyond = 0.0
            for d in range(k):
                index = (out[p, d] - origin[d]) / spacing[d]
                outside = max(-index, index - (shape[d] - 1.0), 0.0) * spacing[d]
                beyond += outside * outside
            number, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1 = _cell(out, p, origin, spacing, shape)
            if not number:
                break
            value = _value(coarse, slots, bricks, x0, x1, y0, y1, z0, z1, a0, a1, b0, b1, c0, c1)
            if beyond > 0:
                value = min(value, -np.sqrt(beyond))
            squared = 0.0
            for q in range(k):
                gradient[q] = _gradient(coarse, slots, bricks, gradients, shape, spacing, x0, x1, y0, y1, z0, z1,
                                        a0, a1, b0, b1, c0, c1, q)
                squared += gradient[q] * gradient[q]
            scale = -value / max(squared, 1e-12)
            length = abs(scale) * np.sqrt(squared)
            if length > limit:
                scale *= limit / length
            for q in range(k):
                out[p, q] += scale * gradient[q]
            if length < settled:
                break
    return out


@kernel
def brick_gradients(coarse, slots, bricks, shape, spacing):
    """(m, B_0, B_1, B_2, k) the central-difference gradient of f on the nodes of each brick kept (0 beyond the
    grid of ``shape`` (3,)): what :func:`interpolate_gradient` reads there.  Each brick's f and that of the nodes
    around it are read once into ``local``, then differenced (:func:`_derivative`, as :func:`_difference`)."""
    gradients = np.zeros((*bricks.shape, len(spacing)))
    index = np.full(bricks.shape[0], -1, np.int64)
    flat = slots.ravel()
    for b in range(flat.size):
        if flat[b] >= 0:
            index[flat[b]] = b
    counts, side = slots.shape, np.array(bricks.shape[1:])
    local = np.zeros((side[0] + 2, side[1] + 2, side[2] + 2))
    corner, at = np.zeros(3, np.int64), np.zeros(3, np.int64)
    for s in range(bricks.shape[0]):
        bx, rest = divmod(index[s], counts[1] * counts[2])
        by, bz = divmod(rest, counts[2])
        corner[0], corner[1], corner[2] = bx * side[0] - 1, by * side[1] - 1, bz * side[2] - 1
        for i in range(side[0] + 2):
            for j in range(side[1] + 2):
                for h in range(side[2] + 2):
                    x, y, z = corner[0] + i, corner[1] + j, corner[2] + h
                    if 0 <= x < shape[0] and 0 <= y < shape[1] and 0 <= z < shape[2]:
                        inner = 0 < i <= side[0] and 0 < j <= side[1] and 0 < h <= side[2]
                        local[i, j, h] = bricks[s, i - 1, j - 1, h - 1] if inner else node_value(
                            coarse, slots, bricks, x, y, z)
        for i in range(1, side[0] + 1):
            for j in range(1, side[1] + 1):
                for h in range(1, side[2] + 1):
                    at[0], at[1], at[2] = corner[0] + i, corner[1] + j, corner[2] + h
                    if at[0] >= shape[0] or at[1] >= shape[1] or at[2] >= shape[2]:
                        continue
                    for q in range(len(spacing)):
                        ahead, behind = int(at[q] < shape[q] - 1), int(at[q] > 0)
                        di, dj, dh = int(q == 0), int(q == 1), int(q == 2)
                        gradients[s, i - 1, j - 1, h - 1, q] = _derivative(
                            local[i + ahead * di, j + ahead * dj, h + ahead * dh],
                            local[i - behind * di, j - behind * dj, h - behind * dh], ahead, behind, spacing[q])
    return gradients


@kernel(parallel=True)
def node_values(coarse, slots, bricks, shape, flat):
    """(m,) f at the nodes with C-order flat indices ``flat`` (m,) of the grid of ``shape`` (3,)."""
    out = np.empty(flat.size)
    for p in prange(flat.size):
        x, rest = divmod(flat[p], shape[1] * shape[2])
        y, z = divmod(rest, shape[2])
        out[p] = node_value(coarse, slots, bricks, x, y, z)
    return out


@kernel
def plane_values(coarse, slots, bricks, shape, first, last):
    """(last - first, n_1, n_2) f on the nodes of the planes ``first`` to ``last`` - 1 along axis 0: row by row
    along axis 2, a brick's run of nodes copied, the refinement's computed from one row of the coarse grid refined
    along axes 0 and 1 (each value as :func:`refined_value` takes it)."""
    out = np.empty((last - first, shape[1], shape[2]))
    row = np.empty(coarse.shape[2])
    for x in range(first, last):
        for y in range(shape[1]):
            refined = False   # row holds the coarse grid refined along axes 0 and 1 at this (x, y)
            for brick in range(slots.shape[2]):
                start = brick << BRICK_SHIFT if slots.size > 1 else 0
                end = min(start + (1 << BRICK_SHIFT), shape[2]) if slots.size > 1 else shape[2]
                slot = 0 if slots.size == 1 else slots[x >> BRICK_SHIFT, y >> BRICK_SHIFT, brick]
                if slot >= 0:
                    bx, by = (x, y) if slots.size == 1 else (x & _MASK, y & _MASK)
                    for z in range(start, end):
                        out[x - first, y, z] = bricks[slot, bx, by, z - start]
                    continue
                if not refined:
                    for cz in range(coarse.shape[2]):
                        row[cz] = _refined_1(coarse, x, y, cz)
                    refined = True
                for z in range(start, end):
                    half = z // 2
                    out[x - first, y, z] = row[half] if z % 2 == 0 else 0.5 * (row[half] + row[half + 1])
    return out


@kernel(parallel=True)
def fill_bricks(coarse, bricks, brick_index, shape):
    """Fill ``bricks`` (m, b_0, b_1, b_2) with the refinement of ``coarse`` over the bricks of (m, 3) indices
    ``brick_index``, nodes beyond the grid of ``shape`` (3,) left at 0."""
    for s in prange(brick_index.shape[0]):
        for i in range(bricks.shape[1]):
            x = brick_index[s, 0] * bricks.shape[1] + i
            for j in range(bricks.shape[2]):
                y = brick_index[s, 1] * bricks.shape[2] + j
                for h in range(bricks.shape[3]):
                    z = brick_index[s, 2] * bricks.shape[3] + h
                    inside = x < shape[0] and y < shape[1] and z < shape[2]
                    bricks[s, i, j, h] = refined_value(coarse, x, y, z) if inside else 0.0
