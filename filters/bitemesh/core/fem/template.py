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
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg
from scipy.spatial import cKDTree

from ..errors import InvalidInputError, MeshingError, check_number, check_points
from ..mesh.simplicial import Mesh, signed_measures
from ..mesh.topology import boundary_facets
from ..progress import ProgressCallback, report
from ..steps.fidelity import distances_to_facets
from ..optimize.measures import mean_edge_length
from .assembly import elasticity_matrix

#: the rounds of iterated closest points of the similarity pre-alignment.
ALIGN_ROUNDS = 50
#: a node is pulled only by data within this many times the median distance between the surfaces and their data
#: (and two edge lengths): a part of a surface that the data does not sample follows the rest, not a far point.
REACH = 3.0
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
    """The similarity that takes the template's surfaces onto their data (``groups``: (node indices, data (n, 3),
    its cKDTree), each surface paired with its own data): the principal axes of both matched (each of the four proper
    ways to pair their directions tried), the RMS sizes and the centroids, then iterated closest points both ways
    within each surface; the start that ends closest wins."""
    surface = points[np.concatenate([nodes for nodes, _, _ in groups])]
    data = np.vstack([targets for _, targets, _ in groups])
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
        found, residual = iterate_closest_points(points, groups, start)
        if best is None or residual < best[1]:
            best = (found, residual)
    return best[0]


def pairs(points: np.ndarray, groups: list):
    """(template points (p, 3), data points (p, 3)): each surface's nodes with their nearest data of that surface,
    and each data point with its nearest node of that surface."""
    sources, targets = [], []
    for nodes, data, tree in groups:
        surface = points[nodes]
        sources += [surface, surface[cKDTree(surface).query(data)[1]]]
        targets += [data[tree.query(surface)[1]], data]
    return np.vstack(sources), np.vstack(targets)


def iterate_closest_points(points: np.ndarray, groups: list, current: tuple):
    """The similarity from ``current`` on, refined by closest points both ways within each surface until it stops
    changing, and the mean distance between the pairs it leaves."""
    for _ in range(ALIGN_ROUNDS):
        moved = current[0] * points @ current[1].T + current[2]
        paired = pairs(moved, groups)
        found = similarity(np.linalg.solve(current[0] * current[1], (paired[0] - current[2]).T).T, paired[1])
        converged = np.allclose(found[1], current[1], rtol=0, atol=1e-13) and \
            abs(found[0] - current[0]) <= 1e-13 * current[0] and \
            np.allclose(found[2], current[2], rtol=0, atol=1e-13 * (1 + np.abs(current[2]).max()))
        current = found
        if converged:
            break
    paired = pairs(current[0] * points @ current[1].T + current[2], groups)
    return current, float(np.linalg.norm(paired[0] - paired[1], axis=1).mean())


def pulled_to(points: np.ndarray, groups: list, reach: float):
    """(targets (n, 3), pulled (n,) bool): each node of a surface pulled halfway between the nearest data point of
    its surface and the mean of the data points whose nearest node of that surface it is (where there are such),
    pairs longer than ``reach`` left out (a part of a surface the data does not sample: no pull); other nodes stay."""
    targets, pulled = points.copy(), np.zeros(len(points), bool)
    for nodes, data, tree in groups:
        surface = points[nodes]
        distance, nearest = tree.query(surface)
        own = data[nearest]
        near = distance <= reach
        apart, claims = cKDTree(surface).query(data)
        claims = claims[apart <= reach]
        counts = np.bincount(claims, minlength=len(nodes))
        sums = np.zeros_like(surface)
        np.add.at(sums, claims, data[apart <= reach])
        claimed = counts > 0
        mean = sums[claimed] / counts[claimed, None]
        own[claimed] = np.where(near[claimed, None], 0.5 * own[claimed] + 0.5 * mean, mean)
        pull = near | claimed
        targets[nodes[pull]] = own[pull]
        pulled[nodes[pull]] = True
    return targets, pulled


def median_gap(points: np.ndarray, groups: list) -> float:
    """The median distance from the data to the nearest node of its surface."""
    return float(np.median(np.concatenate([cKDTree(points[nodes]).query(data)[0] for nodes, data, _ in groups])))


def surface_groups(template: Mesh, data) -> list:
    """(node indices, data points, their cKDTree) per surface: ``data`` an (n, 3) array for the whole boundary, or a
    mapping of the template's facet tag names to the points of that surface (a tag without data is left free)."""
    if not isinstance(data, dict):
        data = check_points(data, dims=(3,))
        if len(data) < 4:
            raise InvalidInputError(f"data: at least 4 points are needed, got {len(data)}")
        return [(np.unique(boundary_facets(template.cells)), data, cKDTree(data))]
    groups = []
    for name, points in data.items():
        if name not in template.tag_names or template.facets is None:
            raise InvalidInputError(f"data: {name!r} is no surface of the template; its surfaces are "
                                    f"{', '.join(sorted(template.tag_names)) or 'none (untagged)'}")
        points = check_points(points, dims=(3,))
        nodes = np.unique(template.facets[template.facet_tags == template.tag_names[name][0]])
        if len(points) and len(nodes):
            groups.append((nodes, points, cKDTree(points)))
    if sum(len(points) for _, points, _ in groups) < 4:
        raise InvalidInputError("data: at least 4 points on the template's surfaces are needed")
    return groups


def fit_template(template: Mesh, data, *, pull: float = 10.0, rounds: int = 40, tolerance: float = 1e-3,
                 progress: ProgressCallback = None) -> TemplateFit:
    """Move a tetrahedral ``template`` onto ``data`` keeping its cells (see the module docstring).

    Parameters
    ----------
    template : Mesh of tetrahedra (its tags and cell data are kept)
    data : (n, 3) float64, points on the surface to fit (input units), n >= 4; or a mapping of the template's
        surface (facet tag) names to the points of each (EPI, LV_ENDO, ...): each surface is pulled to its own
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
    groups = surface_groups(template, data)
    pull = check_number(pull, "pull", low=0, low_open=True, hint="10 pulls the surface close to the data")
    rounds = int(check_number(rounds, "rounds", low=1, high=10000))
    cells = template.cells
    scale, rotation, shift = align(template.points, groups)
    points = scale * template.points @ rotation.T + shift
    edge = mean_edge_length(points, cells)
    step_bound = tolerance * edge
    surfaces = np.unique(np.concatenate([nodes for nodes, _, _ in groups]))
    done = 0
    for done in range(1, rounds + 1):
        report(progress, done / (rounds + 1), f"elastic round {done}")
        stiffness = elasticity_matrix(points, cells)
        weight = pull * float(stiffness.diagonal().reshape(-1, 3)[surfaces].mean())
        reach = max(REACH * median_gap(points, groups), 2 * edge)
        targets, pulled = pulled_to(points, groups, reach)
        springs = np.repeat(np.where(pulled, weight, 0.0), 3)
        system = (stiffness + sparse.diags(springs)).tocsc()
        step = splinalg.spsolve(system, springs * (targets - points).ravel()).reshape(-1, 3)
        points, taken = positive_step(points, cells, step)
        if taken * np.abs(step).max() < step_bound:
            break
    moved = Mesh(points, cells, dict(template.cell_data), template.facets, template.facet_tags,
                 dict(template.tag_names))
    distances = distances_to_facets(np.vstack([data for _, data, _ in groups]), points[boundary_facets(cells)])
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
