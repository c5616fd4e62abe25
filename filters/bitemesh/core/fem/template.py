"""The deformable elastic template of the paper (section 2): a tetrahedral mesh moved onto new data by minimising
E = E_elastic + E_data, discretised as K U = F, with the same cells.

Scheme.  First a similarity (rotation, uniform scale, translation) takes the template's boundary onto the data:
iterated closest points with Umeyama's closed form, so that a pure rigid motion or scaling is recovered exactly and
the elastic part only has to bend.  Then rounds of the elastic fit on the updated geometry: each boundary node is
pulled towards the nearest data point by a spring of stiffness ``pull`` (relative to the mean diagonal of the
stiffness at the boundary), the template's own P1 linear-elasticity stiffness K (assembled on the current points:
an updated Lagrangian, so that large deformations are taken in small linear steps) holds the rest, and
(K + P) U = P (targets - points) gives the step.  A step that would invert a cell is halved until none does; the
rounds stop when the largest step is below ``tolerance`` x the template's mean edge length.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg
from scipy.spatial import cKDTree

from ..errors import InvalidInputError, MeshingError, check_number, check_points
from ..mesh.simplicial import Mesh, signed_measures
from ..mesh.topology import boundary_facets
from ..progress import ProgressCallback, report
from ..steps.fidelity import distances_to_facets
from .assembly import elasticity_matrix

#: the rounds of iterated closest points of the similarity pre-alignment.
ALIGN_ROUNDS = 50
#: the most halvings of a step that would invert a cell, and the smallest share of its volume a cell may keep in
#: one step (a step that flattens a cell is halved too).
HALVINGS, SHRINK = 12, 0.05


@dataclass(frozen=True, eq=False)
class TemplateFit:
    """A template moved onto data.

    Attributes
    ----------
    mesh : the template's cells and tags on the moved points (input units of the data)
    similarity : (scale, rotation (3, 3), translation (3,)): the pre-alignment, x -> scale R x + t
    rounds : elastic rounds run; seconds : wall clock of the fit
    distances : (n,) float64, each data point's distance to the moved mesh's boundary (input units)
    """

    mesh: Mesh
    similarity: tuple
    rounds: int
    distances: np.ndarray
    seconds: float = 0.0
    notes: tuple = field(default=())


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


def align(points: np.ndarray, boundary: np.ndarray, data: np.ndarray, tree: cKDTree):
    """The similarity that takes the ``boundary`` nodes of ``points`` onto the ``data`` (tree: its cKDTree): the
    principal axes of both matched (each of the four proper ways to pair their directions tried), the RMS sizes and
    the centroids, then iterated closest points both ways; the start that ends closest wins."""
    surface = points[boundary]
    axes_from = np.linalg.eigh(np.cov(surface.T))[1]
    axes_to = np.linalg.eigh(np.cov(data.T))[1]
    size = np.sqrt(np.mean(np.sum((data - data.mean(axis=0)) ** 2, axis=1))
                   / np.mean(np.sum((surface - surface.mean(axis=0)) ** 2, axis=1)))
    best = None
    for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
        turn = axes_to @ np.diag(signs) @ axes_from.T
        if np.linalg.det(turn) < 0:
            turn = axes_to @ np.diag(signs) @ np.diag([1, 1, -1]) @ axes_from.T
        start = (float(size), turn, data.mean(axis=0) - size * turn @ surface.mean(axis=0))
        found, residual = iterate_closest_points(surface, data, tree, start)
        if best is None or residual < best[1]:
            best = (found, residual)
    return best[0]


def iterate_closest_points(surface: np.ndarray, data: np.ndarray, tree: cKDTree, current: tuple):
    """The similarity from ``current`` on, refined by closest points both ways until it stops changing, and the
    mean closest distance both ways it leaves."""
    for _ in range(ALIGN_ROUNDS):
        moved = current[0] * surface @ current[1].T + current[2]
        nearest_data = tree.query(moved)[1]
        nearest_node = cKDTree(moved).query(data)[1]
        found = similarity(np.vstack([surface, surface[nearest_node]]), np.vstack([data[nearest_data], data]))
        converged = np.allclose(found[1], current[1], rtol=0, atol=1e-13) and \
            abs(found[0] - current[0]) <= 1e-13 * current[0] and \
            np.allclose(found[2], current[2], rtol=0, atol=1e-13 * (1 + np.abs(current[2]).max()))
        current = found
        if converged:
            break
    moved = current[0] * surface @ current[1].T + current[2]
    return current, float(tree.query(moved)[0].mean() + cKDTree(moved).query(data)[0].mean())


def fit_template(template: Mesh, data, *, pull: float = 10.0, rounds: int = 40, tolerance: float = 1e-3,
                 progress: ProgressCallback = None) -> TemplateFit:
    """Move a tetrahedral ``template`` onto ``data`` keeping its cells (see the module docstring).

    Parameters
    ----------
    template : Mesh of tetrahedra (its tags and cell data are kept)
    data : (n, 3) float64, points on the surface to fit (input units), n >= 4
    pull : the springs' stiffness relative to the template's (larger: closer to the data, less smooth), > 0
    rounds : the most elastic rounds, >= 1; tolerance : the step, in mean edge lengths, that ends them
    progress : callable(fraction, message), optional

    Returns
    -------
    TemplateFit; raises MeshingError when no step keeps every cell positive
    """
    start = time.perf_counter()
    if template.dim != 3:
        raise InvalidInputError(f"template: a tetrahedral mesh is needed, got a {template.dim}D mesh")
    data = check_points(data, dims=(3,))
    if len(data) < 4:
        raise InvalidInputError(f"data: at least 4 points are needed, got {len(data)}")
    pull = check_number(pull, "pull", low=0, low_open=True, hint="10 pulls the surface close to the data")
    rounds = int(check_number(rounds, "rounds", low=1, high=10000))
    cells = template.cells
    boundary = np.unique(boundary_facets(cells))
    tree = cKDTree(data)
    scale, rotation, shift = align(template.points, boundary, data, tree)
    points = scale * template.points @ rotation.T + shift
    edges = points[cells[:, [0, 0, 0, 1, 1, 2]]] - points[cells[:, [1, 2, 3, 2, 3, 3]]]
    step_bound = tolerance * float(np.linalg.norm(edges, axis=2).mean())
    dofs = (3 * boundary[:, None] + np.arange(3)).ravel()
    done = 0
    for done in range(1, rounds + 1):
        report(progress, done / (rounds + 1), f"elastic round {done}")
        stiffness = elasticity_matrix(points, cells)
        weight = pull * float(stiffness.diagonal()[dofs].mean())
        springs = np.zeros(3 * len(points))
        springs[dofs] = weight
        targets = points.copy()
        targets[boundary] = data[tree.query(points[boundary])[1]]
        # the data's own pull: each data point on its nearest boundary node (a sparse region is not skipped)
        nearest = boundary[cKDTree(points[boundary]).query(data)[1]]
        counts = np.bincount(nearest, minlength=len(points))
        sums = np.zeros_like(points)
        np.add.at(sums, nearest, data)
        claimed = counts > 0
        targets[claimed] = 0.5 * targets[claimed] + 0.5 * sums[claimed] / counts[claimed, None]
        system = (stiffness + sparse.diags(springs)).tocsc()
        step = splinalg.spsolve(system, springs * (targets - points).ravel()).reshape(-1, 3)
        points, taken = positive_step(points, cells, step)
        if taken * np.abs(step).max() < step_bound:
            break
    moved = Mesh(points, cells, dict(template.cell_data), template.facets, template.facet_tags,
                 dict(template.tag_names))
    distances = distances_to_facets(data, points[boundary_facets(cells)])
    report(progress, 1.0, "fitted")
    return TemplateFit(moved, (scale, rotation, shift), done, distances, time.perf_counter() - start)


def positive_step(points: np.ndarray, cells: np.ndarray, step: np.ndarray):
    """(points + t step, t) for the largest t in 1, 1/2, 1/4, ... that keeps every cell positive and no smaller
    than :data:`SHRINK` of its volume before the step."""
    before = signed_measures(points, cells)
    fraction = 1.0
    for _ in range(HALVINGS):
        moved = points + fraction * step
        if (signed_measures(moved, cells) > SHRINK * before).all():
            return moved, fraction
        fraction /= 2
    raise MeshingError("the fit would invert cells at every step size; lower pull, or pre-align the template "
                       "with the data (a far smaller or far larger template needs a similar size first)")
