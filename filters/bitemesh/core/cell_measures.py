"""Measures of cells and nodes that the optimizer moves and flips by: the signed radius ratio, Knupp's mean ratio
and its gradient, the smallest angles, the mean edge length, the boundary nodes and those off f = 0.
"""
from __future__ import annotations

from math import factorial

import numpy as np

from .grid import ImplicitGrid
from .kernels import kernel
from .quality import cross, dihedral_angles, dot, edge_lengths, signed_radius_ratio  # noqa: F401 (re-exported)
from .topology import boundary_facets

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


def mean_ratio_terms(corners: np.ndarray):
    """What :func:`mean_ratio_cost` and its derivatives need, for (m, k + 1, k) ``corners``.

    Returns
    -------
    volume : (m,) signed measure
    squares : (m,) sum of the squared edge lengths
    volume_gradient : (m, k + 1, k) d volume / d vertex; the volume is linear in each vertex, so
        volume + volume_gradient[:, i] . d is exact when vertex i alone moves by d
    centred : (m, k + 1, k) the vertices minus their mean; when vertex i alone moves by d, squares grows by
        2 (k + 1) centred[:, i] . d + k |d|^2
    """
    k = corners.shape[-1]
    edges = corners[:, 1:] - corners[:, :1]
    # d V / d x_i for i >= 1: the cofactors of the edge matrix; d V / d x_0 = -(their sum)
    if k == 2:
        cofactors = np.stack([np.stack([edges[:, 1, 1], -edges[:, 1, 0]], axis=1),
                              np.stack([-edges[:, 0, 1], edges[:, 0, 0]], axis=1)], axis=1)
    else:
        cofactors = np.stack([cross(edges[:, 1], edges[:, 2]), cross(edges[:, 2], edges[:, 0]),
                              cross(edges[:, 0], edges[:, 1])], axis=1)
    cofactors /= factorial(k)
    volume = dot(edges[:, 0], cofactors[:, 0])
    volume_gradient = np.concatenate([-cofactors.sum(axis=1, keepdims=True), cofactors], axis=1)
    total = edges.sum(axis=1)
    squares = (k + 1) * np.einsum("mij,mij->m", edges, edges) - dot(total, total)
    centred = np.concatenate([np.zeros_like(edges[:, :1]), edges], axis=1) - total[:, None] / (k + 1)
    return volume, squares, volume_gradient, centred


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


def inverse_mean_ratio(corners: np.ndarray) -> np.ndarray:
    """(m,) :func:`mean_ratio_cost` of the simplices with (m, k + 1, k) ``corners``."""
    k = corners.shape[-1]
    edges = corners[:, 1:] - corners[:, :1]
    if k == 2:
        volume = 0.5 * (edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0])
    else:
        volume = dot(edges[:, 0], cross(edges[:, 1], edges[:, 2])) / 6.0
    total = edges.sum(axis=1)
    squares = (k + 1) * np.einsum("mij,mij->m", edges, edges) - dot(total, total)
    return mean_ratio_cost(volume, squares, k)


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
