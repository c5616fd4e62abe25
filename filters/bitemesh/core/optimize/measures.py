"""Measures of cells and nodes that the optimizer moves and flips by: the signed radius ratio, Knupp's mean ratio
and its gradient, the smallest angles, the mean edge length, the boundary nodes and those off f = 0.
"""
from __future__ import annotations

import numpy as np
from numba import prange

from ..grid.sampled import ImplicitGrid
from ..compiled import kernel
from ..mesh.quality import _BLOCK, dihedral_angles, dot, edge_lengths
from ..mesh.topology import boundary_facets

#: sum of squared edge lengths / V^(2/k) of the regular triangle and tetrahedron.
MEAN_RATIO_SCALE = {2: 4.0 * np.sqrt(3.0), 3: 12.0 * 3.0 ** (2.0 / 3.0)}


def mean_ratio_cost(volume: np.ndarray, squares: np.ndarray, k: int) -> np.ndarray:
    """(m,) 1 / mean ratio of simplices of signed measure ``volume`` and sum of squared edge lengths ``squares``.

    The mean ratio is eta = C_k V^(2/k) / (sum of squared edge lengths), 1 for the regular simplex.  1 / eta is
    smooth, >= 1, and grows without bound as a cell flattens (inf for no or negative volume): a descent on it
    cannot invert a cell.
    """
    cost = np.full(len(volume), np.inf)
    positive = volume > 0
    cost[positive] = squares[positive] / (MEAN_RATIO_SCALE[k] * volume[positive] ** (2.0 / k))
    return cost


@kernel
def _lane_sum(products: np.ndarray, count: int) -> float:
    """The sum of ``products[:count]`` in numpy einsum's order on this build (two lanes, eight products at a time
    from the front, then pairs; checked in tests/core/optimize/test_optimize.py), so that the kernels' sums are numpy's
    bit for bit."""
    low = high = 0.0
    start = 0
    while count - start >= 8:
        low = products[start] + (products[start + 2] + (products[start + 4] + (products[start + 6] + low)))
        high = products[start + 1] + (products[start + 3] + (products[start + 5] + (products[start + 7] + high)))
        start += 8
    for i in range(start, count, 2):
        low = products[i] + low
        if i + 1 < count:
            high = products[i + 1] + high
    return low + high


@kernel
def _edge_terms(points: np.ndarray, cell: np.ndarray, edges: np.ndarray, total: np.ndarray,
                scratch: np.ndarray) -> float:
    """Fill ``edges`` (k, k) (vertex j + 1 minus vertex 0) and ``total`` (k,) (their sum) of the cell with (k + 1,)
    vertices ``cell`` of the (n, k) ``points``; return its sum of squared edge lengths."""
    k = points.shape[1]
    for j in range(k):
        for d in range(k):
            edges[j, d] = points[cell[j + 1], d] - points[cell[0], d]
            scratch[j * k + d] = edges[j, d] * edges[j, d]
    for d in range(k):
        total[d] = edges[0, d] + edges[1, d]
        if k == 3:
            total[d] += edges[2, d]
    squared = _lane_sum(scratch, k * k)
    for d in range(k):
        scratch[d] = total[d] * total[d]
    return (k + 1) * squared - _lane_sum(scratch, k)


@kernel(parallel=True)
def mean_ratio_terms(points: np.ndarray, cells: np.ndarray):
    """What :func:`mean_ratio_cost` and its derivatives need, for the (m, k + 1) ``cells`` of (n, k) ``points``.

    Returns
    -------
    volume : (m,) signed measure
    squares : (m,) sum of the squared edge lengths
    volume_gradient : (m, k + 1, k) d volume / d vertex; the volume is linear in each vertex, so
        volume + volume_gradient[:, i] . d is exact when vertex i alone moves by d
    centred : (m, k + 1, k) the vertices minus their mean; when vertex i alone moves by d, squares grows by
        2 (k + 1) centred[:, i] . d + k |d|^2
    """
    m, k = len(cells), points.shape[1]
    volume, squares = np.empty(m), np.empty(m)
    volume_gradient, centred = np.empty((m, k + 1, k)), np.empty((m, k + 1, k))
    for block in prange((m + _BLOCK - 1) // _BLOCK):
        edges, total, scratch = np.empty((k, k)), np.empty(k), np.empty(k * k)
        for c in range(block * _BLOCK, min(m, (block + 1) * _BLOCK)):
            squares[c] = _edge_terms(points, cells[c], edges, total, scratch)
            # d V / d x_i for i >= 1: the cofactors of the edge matrix, / k!; d V / d x_0 = -(their sum)
            cofactors = volume_gradient[c, 1:]
            if k == 2:
                cofactors[0, 0], cofactors[0, 1] = edges[1, 1] / 2.0, -edges[1, 0] / 2.0
                cofactors[1, 0], cofactors[1, 1] = -edges[0, 1] / 2.0, edges[0, 0] / 2.0
            else:
                for i in range(3):
                    a, b = edges[(i + 1) % 3], edges[(i + 2) % 3]
                    cofactors[i, 0] = (a[1] * b[2] - a[2] * b[1]) / 6.0
                    cofactors[i, 1] = (a[2] * b[0] - a[0] * b[2]) / 6.0
                    cofactors[i, 2] = (a[0] * b[1] - a[1] * b[0]) / 6.0
            for d in range(k):
                scratch[d] = edges[0, d] * cofactors[0, d]
                summed = cofactors[0, d] + cofactors[1, d]
                if k == 3:
                    summed += cofactors[2, d]
                volume_gradient[c, 0, d] = -summed
                share = total[d] / (k + 1)
                centred[c, 0, d] = 0.0 - share
                for j in range(k):
                    centred[c, j + 1, d] = edges[j, d] - share
            volume[c] = _lane_sum(scratch, k)
    return volume, squares, volume_gradient, centred


@kernel(parallel=True)
def _inverse_mean_ratio(points: np.ndarray, cells: np.ndarray, scale: float) -> np.ndarray:
    m, k = len(cells), points.shape[1]
    cost = np.empty(m)
    for block in prange((m + _BLOCK - 1) // _BLOCK):
        edges, total, scratch = np.empty((k, k)), np.empty(k), np.empty(k * k)
        for c in range(block * _BLOCK, min(m, (block + 1) * _BLOCK)):
            squares = _edge_terms(points, cells[c], edges, total, scratch)
            if k == 2:
                volume = 0.5 * (edges[0, 0] * edges[1, 1] - edges[0, 1] * edges[1, 0])
            else:
                scratch[0] = edges[0, 0] * (edges[1, 1] * edges[2, 2] - edges[1, 2] * edges[2, 1])
                scratch[1] = edges[0, 1] * (edges[1, 2] * edges[2, 0] - edges[1, 0] * edges[2, 2])
                scratch[2] = edges[0, 2] * (edges[1, 0] * edges[2, 1] - edges[1, 1] * edges[2, 0])
                volume = _lane_sum(scratch, 3) / 6.0
            cost[c] = squares / (scale * volume ** (2.0 / k)) if volume > 0 else np.inf
    return cost


def inverse_mean_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) :func:`mean_ratio_cost` of the (m, k + 1) ``cells`` of (n, k) ``points``."""
    points = np.asarray(points, dtype=np.float64)
    return _inverse_mean_ratio(points, np.asarray(cells, dtype=np.int64), MEAN_RATIO_SCALE[points.shape[-1]])


@kernel
def node_trial_costs(cells: np.ndarray, volume: np.ndarray, squares: np.ndarray, volume_gradient: np.ndarray,
                     centred: np.ndarray, move: np.ndarray, n_points: int, power: int) -> np.ndarray:
    """(n_points,) for each node, sum over its cells of :func:`mean_ratio_cost` ** ``power`` when that node alone
    moves by ``move`` (n_points, k), from the cells' :func:`mean_ratio_terms` (exact: see there)."""
    m, corners, k = volume_gradient.shape
    scale = 4.0 * np.sqrt(3.0) if k == 2 else 12.0 * 3.0 ** (2.0 / 3.0)
    # the sums over the axes in the order of numpy's einsum (0, 2, 1 in 3D), so that the result is the same
    axes = np.array([0, 2, 1]) if k == 3 else np.array([0, 1])
    total = np.zeros(n_points)
    for c in range(m):
        for i in range(corners):
            node = cells[c, i]
            trial_volume, trial_squares = 0.0, 0.0
            for d in axes:
                shift = move[node, d]
                trial_volume += volume_gradient[c, i, d] * shift
                trial_squares += (2.0 * corners * centred[c, i, d] + k * shift) * shift
            trial_volume += volume[c]
            trial_squares += squares[c]
            if trial_volume > 0:
                total[node] += (trial_squares / (scale * trial_volume ** (2.0 / k))) ** power
            else:
                total[node] += np.inf
    return total


@kernel
def node_cost_descent(cells: np.ndarray, cost: np.ndarray, squares: np.ndarray, volume: np.ndarray,
                      volume_gradient: np.ndarray, centred: np.ndarray, n_points: int, power: int):
    """For each node, the sum over its cells of ``cost`` ** ``power`` (n_points,) and minus its gradient with
    respect to the node (n_points, k), from the cells' :func:`mean_ratio_cost` and :func:`mean_ratio_terms`;
    not finite at a node with a cell of infinite cost."""
    m, corners, k = volume_gradient.shape
    current, gradient = np.zeros(n_points), np.zeros((n_points, k))
    for c in range(m):
        raised = cost[c] ** power
        weight = power * raised
        for i in range(corners):
            node = cells[c, i]
            current[node] += raised
            for d in range(k):
                if np.isfinite(weight):
                    gradient[node, d] += weight * ((2.0 * corners) * centred[c, i, d] / squares[c]
                                                   - (2.0 / k) * volume_gradient[c, i, d] / volume[c])
                else:
                    gradient[node, d] += np.nan
    return current, -gradient


def smallest_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) the smallest dihedral angle (3D) or interior angle (2D) of each cell, degrees; 0 for a flat cell."""
    return np.nan_to_num(dihedral_angles(points, cells).min(axis=1), nan=0.0)


def mean_edge_length(points: np.ndarray, cells: np.ndarray) -> float:
    return float(edge_lengths(points, cells)[1].mean())


def boundary_nodes(cells: np.ndarray, n_points: int) -> np.ndarray:
    """(n_points,) bool, True for the vertices of the boundary facets."""
    on_boundary = np.zeros(n_points, bool)
    on_boundary[boundary_facets(cells).ravel()] = True
    return on_boundary


def off_surface_nodes(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, tolerance: float) -> np.ndarray:
    """The boundary nodes where |f| exceeds ``tolerance``."""
    nodes = np.flatnonzero(boundary_nodes(cells, len(points)))
    return nodes[np.abs(grid.evaluate(points[nodes])) > tolerance]


def scatter_to_points(n_points: int, simplices: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(n_points, k) the sums at each vertex of ``values`` (m, j, k), one row per corner of the (m, j) simplices."""
    flat = values.reshape(simplices.size, -1)
    return np.stack([np.bincount(simplices.ravel(), flat[:, d], n_points) for d in range(flat.shape[1])], axis=1)


def tangential(grid: ImplicitGrid, points: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``vectors`` at ``points`` without their component along grad f."""
    gradient = grid.gradient(points)
    normals = gradient / np.maximum(np.linalg.norm(gradient, axis=1, keepdims=True), 1e-300)
    return vectors - dot(vectors, normals)[:, None] * normals
