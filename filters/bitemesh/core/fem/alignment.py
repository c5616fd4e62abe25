"""The similarity pre-alignment of the elastic template (:mod:`bitemesh.core.fem.template`): rotation, uniform scale
and translation that take a template's surfaces onto their data, by Umeyama's closed form within iterated closest
points from several starts.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the rounds of iterated closest points of the similarity pre-alignment.
ALIGN_ROUNDS = 50


def similarity(source: np.ndarray, target: np.ndarray):
    """(scale, rotation, translation) minimising |scale R source + t - target|^2 over paired (n, 3) points
    (Umeyama 1991): a proper rotation, scale > 0."""
    source_mean, target_mean = source.mean(axis=0), target.mean(axis=0)
    a, b = source - source_mean, target - target_mean
    u, singular, vt = np.linalg.svd(b.T @ a / len(a))
    sign = np.ones(3)
    sign[2] = np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0
    rotation = u @ np.diag(sign) @ vt
    scale = float((singular * sign).sum() / np.mean(np.sum(a * a, axis=1)))
    return scale, rotation, target_mean - scale * rotation @ source_mean


def align(points: np.ndarray, groups: list):
    """The similarity that takes the template's surfaces onto their data (``groups``: see
    :func:`surface_groups`).  Starts: the template where it is, and the principal
    axes of both matched (each of the four proper ways to pair their directions), with the RMS sizes and the
    centroids; each refined by iterated closest points from the data to its surface (the data may sample a surface in
    part: contours); the start that ends closest wins."""
    surface = points[np.concatenate([nodes for nodes, _, _, _ in groups])]
    data = np.vstack([targets for _, _, targets, _ in groups])
    axes_from = np.linalg.eigh(np.cov(surface.T))[1]
    axes_to = np.linalg.eigh(np.cov(data.T))[1]
    size = np.sqrt(np.mean(np.sum((data - data.mean(axis=0)) ** 2, axis=1))
                   / np.mean(np.sum((surface - surface.mean(axis=0)) ** 2, axis=1)))
    starts = [(1.0, np.eye(3), np.zeros(3))]
    for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
        turn = axes_to @ np.diag(signs) @ axes_from.T
        if np.linalg.det(turn) < 0:
            turn = axes_to @ np.diag(signs) @ np.diag([1, 1, -1]) @ axes_from.T
        starts.append((float(size), turn, data.mean(axis=0) - size * turn @ surface.mean(axis=0)))
    best, paired = None, nearest_pairs(points, groups)
    for start in starts:
        found, residual = iterate_closest_points(paired, start)
        if best is None or residual < best[1]:
            best = (found, residual)
    return best[0]


def nearest_pairs(points: np.ndarray, groups: list):
    """A callable: a similarity (scale, rotation, shift) -> (template points (p, 3), data points (p, 3)), each data
    point with the nearest node of its surface once the template is moved by it: the data moved back into the
    template's frame instead (a similarity keeps which node is nearest), so that each surface's k-d tree is built
    once."""
    surfaces = [(points[nodes], cKDTree(points[nodes]), data) for nodes, _, data, _ in groups]
    targets = np.vstack([data for _, _, data in surfaces])

    def paired(current: tuple):
        scale, rotation, shift = current
        return np.vstack([surface[tree.query((data - shift) @ rotation / scale)[1]]
                          for surface, tree, data in surfaces]), targets
    return paired


def iterate_closest_points(paired, current: tuple):
    """The similarity from ``current`` on, refined by closest points within each surface (``paired``:
    :func:`nearest_pairs`) until it stops changing, and the mean distance between the pairs it leaves."""
    for _ in range(ALIGN_ROUNDS):
        found = similarity(*paired(current))
        converged = np.allclose(found[1], current[1], rtol=0, atol=1e-13) and \
            abs(found[0] - current[0]) <= 1e-13 * current[0] and \
            np.allclose(found[2], current[2], rtol=0, atol=1e-13 * (1 + np.abs(current[2]).max()))
        current = found
        if converged:
            break
    source, target = paired(current)
    return current, float(np.linalg.norm(current[0] * source @ current[1].T + current[2] - target, axis=1).mean())
