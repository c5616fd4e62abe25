"""Mesh optimisation: the relaxation and the sliver removal that the paper leaves to future work (sections 5-6).

1. Boundary nodes: every node on the boundary of the mesh goes onto f = 0 (Newton steps along grad f,
   :func:`bitemesh.core.biting.project_to_surface`) and every later move keeps it there.
2. Relaxation (:func:`relax`): optimal Delaunay triangulation (ODT) smoothing, Alliez et al. 2005.  Each interior
   node moves to the volume-weighted mean of the circumcentres of its cells, each boundary node towards the
   area-weighted mean of the centroids of its boundary facets, along the surface and back onto f = 0; then the
   nodes are triangulated again (Delaunay and the circumcentre test), until the mean radius ratio stops rising.
   The last state is carved into a valid domain (:func:`bitemesh.core.domain.carve_domain`).
3. Sliver removal (:func:`remove_slivers`): rounds of flips (:mod:`bitemesh.core.flips`), which replace the cells
   around an interior edge (edge removal: 3-2, 4-4, 5-6 ... flips) or on both sides of an interior facet (2-3 flips;
   2-2 in 2D) when that raises the worst radius ratio among them, then of smoothing (:func:`smooth`), which moves the
   nodes down sum over the cells of (1 / mean ratio)^2 (Knupp's inverse mean ratio, infinite for a flat cell) with the
   boundary nodes sliding on f = 0.  A poor cell left (an angle below ``min_dihedral`` or a radius ratio below
   ``min_quality``) that lies on the surface is peeled (:func:`peel`).  The rounds end when no cell is poor (within
   ``SLIVER_ROUNDS``).
4. Nothing turns a valid mesh into an invalid one: flips only replace cells inside the domain and smoothing keeps
   every cell positive; :func:`bitemesh.core.quality.check_valid_domain` then judges the states met, and the best
   valid one is returned (the input itself when nothing did better).  Nor does anything change its topology (the
   boundary's components and Euler characteristic, :func:`topology`): a relaxation that opened or closed a hole
   through a wall thinner than about a cell is abandoned, and the sliver removal starts from the input.

The nodes are the biting's, only moved (the carving may drop one that no cell inside uses): the node spacing stays
uniform.  Everything is deterministic.  Measured on a sphere of 10,000 cells (``tests/core/test_optimize.py``): mean
radius ratio 0.81 -> 0.90, smallest dihedral angle 0.6 -> 32 degrees, edge-length CV 0.17 -> 0.12, in 2.5 s,
about 9 times the mesh steps before it (biting, Delaunay, carving) and 1.8 times the whole pipeline from scattered
points.
"""
from __future__ import annotations

import warnings

import numpy as np

from .biting import project_to_surface
from .cell_measures import (boundary_nodes, cross, dot, inverse_mean_ratio, mean_edge_length, mean_ratio_cost,
                            mean_ratio_terms, off_surface_nodes, scatter_to_points, signed_radius_ratio,
                            smallest_angles, tangential)
from .delaunay import delaunay
from .domain import carve_domain, compact
from .errors import BitemeshWarning, InvalidInputError, MeshingError
from .flips import flip
from .grid import ImplicitGrid
from .mesh import Mesh, circumspheres, signed_measures
from .parameters import OptimizeParameters, SpuriousParameters
from .progress import ProgressCallback, report, sub_progress
from .quality import boundary_euler_characteristic, check_valid_domain, count_boundary_components
from .spurious import outside_cells
from .topology import boundary_facets, facet_table, non_manifold_faces

#: the relaxation, and the rounds of sliver removal once no cell is below the angle bound, stop when the mean
#: radius ratio has not risen by MEAN_GAIN over their last PATIENCE iterations (rounds: over the last one).
MEAN_GAIN = 2e-3
PATIENCE = 2
#: rounds of carving the relaxed nodes into a domain and moving the boundary nodes it left off f = 0.
SURFACE_ROUNDS = 3
#: an interior node may come no closer to f = 0 than this fraction of the mean edge length.
INTERIOR_MARGIN = 0.3
#: rounds of flips and smoothing, and the smoothing iterations in each round.
SLIVER_ROUNDS = 4
SMOOTH_ITERATIONS = 6
#: smoothing: exponent p of the cost (1 / mean ratio)^p, longest move (x mean edge length), the step lengths tried.
SMOOTH_POWER = 2
MAX_MOVE = 0.2
STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.125)
#: rounds in which moves that made a shared cell worse are taken back (smoothing), or in which peeled cells that
#: pinched the boundary come back (peel).
REVERT_ROUNDS = 10
#: a boundary node is on the surface when |f| there is below this fraction of the mean edge length.
SURFACE_TOLERANCE = 0.01


# --- relaxation ----------------------------------------------------------------------------------------------------

def odt_targets(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, margin: float) -> np.ndarray:
    """(n, k) where the ODT smoothing moves each node (Alliez et al. 2005, section 4).

    Interior nodes: the volume-weighted mean of the circumcentres of their cells, pushed back to f = ``margin``
    when it lies closer to the surface.  Boundary nodes: the area-weighted mean of the centroids of their boundary
    facets, the move taken along the surface, then onto f = 0.  A node in no cell with volume stays.
    """
    n, k = points.shape
    centres, _ = circumspheres(points, cells)
    volume = np.abs(signed_measures(points, cells))
    usable = np.isfinite(centres).all(axis=1)
    weight = np.bincount(cells[usable].ravel(), np.repeat(volume[usable], k + 1), n)
    weighted = np.repeat((volume[usable, None] * centres[usable])[:, None], k + 1, axis=1)
    targets = points.copy()
    inner = np.flatnonzero(weight > 0)
    targets[inner] = scatter_to_points(n, cells[usable], weighted)[inner] / weight[inner, None]

    facets = boundary_facets(cells)
    corners = points[facets]
    spans = corners[:, 1:] - corners[:, :1]
    area = np.linalg.norm(cross(spans[:, 0], spans[:, 1]) if k == 3 else spans[:, 0], axis=1)
    along = scatter_to_points(n, facets, np.repeat((area[:, None] * corners.mean(axis=1))[:, None], k, axis=1))
    along_weight = np.bincount(facets.ravel(), np.repeat(area, k), n)

    on_boundary = boundary_nodes(cells, n)
    inner = np.flatnonzero(~on_boundary)
    value = grid.evaluate(targets[inner])
    shallow = inner[value < margin]
    if len(shallow):
        gradient = grid.gradient(targets[shallow])
        squared = np.maximum(dot(gradient, gradient), 1e-12)
        targets[shallow] += ((margin - value[value < margin]) / squared)[:, None] * gradient
    outer = np.flatnonzero(on_boundary & (along_weight > 0))
    goal = along[outer] / along_weight[outer, None]
    targets[outer] = project_to_surface(grid, points[outer] + tangential(grid, points[outer], goal - points[outer]))
    return targets


def relax(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
          spurious: SpuriousParameters = SpuriousParameters(), progress: ProgressCallback = None):
    """ODT relaxation: move the nodes (:func:`odt_targets`), triangulate them again, keep the cells inside; repeat.

    Between the moves only the circumcentre test of the spurious-cell filter sorts the cells (fast); the last state
    is carved into a valid domain, and moved and carved again while that left boundary nodes off f = 0 (at most
    ``SURFACE_ROUNDS`` times).  Stops after ``iterations`` moves, or when the mean radius ratio has not risen by
    ``MEAN_GAIN`` over ``PATIENCE`` iterations.  Nodes that no cell inside uses are dropped.

    Returns
    -------
    points, cells : the relaxed valid mesh
    history : list of float, the mean radius ratio after each move

    Raises :class:`MeshingError` when the moved nodes leave no cell inside or cannot be carved into a valid domain.
    """
    length = mean_edge_length(points, cells)
    margin = INTERIOR_MARGIN * length
    history = []
    for iteration in range(iterations):
        moved = odt_targets(grid, points, cells, margin)
        triangulation = delaunay(moved)
        inside = triangulation[~outside_cells(grid, moved, triangulation, spurious.threshold)]
        if len(inside) == 0:
            raise MeshingError("the relaxed nodes leave no cell inside the domain")
        relaxed = compact(moved, inside)
        points, cells = relaxed.points, relaxed.cells
        history.append(float(signed_radius_ratio(points, cells).mean()))
        report(progress, (iteration + 1) / iterations,
               f"relaxation {iteration + 1}/{iterations}: mean radius ratio {history[-1]:.4f}")
        if len(history) > PATIENCE and max(history[-PATIENCE:]) < max(history[:-PATIENCE]) + MEAN_GAIN:
            break
    for round_ in range(SURFACE_ROUNDS):
        if round_:  # the carving laid nodes bare: move them onto f = 0, with the others
            points = odt_targets(grid, points, cells, margin)
        mesh = carve_domain(grid, points, delaunay(points), spurious)
        points, cells = mesh.points, mesh.cells
        if len(off_surface_nodes(grid, points, cells, SURFACE_TOLERANCE * length)) == 0:
            break
    report(progress, 1.0, f"relaxation: {len(history)} iterations, mean radius ratio "
                          f"{signed_radius_ratio(points, cells).mean():.4f} in the carved domain")
    return points, cells, history


# --- smoothing -----------------------------------------------------------------------------------------------------

def smooth(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
           progress: ProgressCallback = None) -> np.ndarray:
    """Move the nodes to lower sum over the cells of (1 / mean ratio)^p; the cells stay as they are.

    Each iteration takes, for every node, a step down the gradient of the cost of its cells (boundary nodes: its
    tangential part, then back onto f = 0): the best of ``STEP_FRACTIONS`` with the other nodes fixed (exact and
    cheap: a cell's volume is linear in one vertex).  All nodes move at once; a node whose cells then cost more
    than before, or one of which is inverted, goes back.  A boundary node off f = 0 goes onto it as soon as its
    cells stay positive there.

    Returns
    -------
    (n, k) float64, the new node positions
    """
    n, k = points.shape
    corner_of = cells.ravel()
    degree = np.bincount(corner_of, minlength=n)
    on_boundary = np.flatnonzero(boundary_nodes(cells, n))
    length = mean_edge_length(points, cells)
    for iteration in range(iterations):
        report(progress, iteration / iterations, f"smoothing {iteration + 1}/{iterations}")
        volume, squares, volume_gradient, centred = mean_ratio_terms(points[cells])
        cost = mean_ratio_cost(volume, squares, k)
        with np.errstate(all="ignore"):  # inf on cells with no volume: their nodes do not move
            gradient = (SMOOTH_POWER * cost ** SMOOTH_POWER)[:, None, None] * (
                2.0 * (k + 1) * centred / squares[:, None, None] - (2.0 / k) * volume_gradient / volume[:, None, None])
        current = np.bincount(corner_of, np.repeat(cost ** SMOOTH_POWER, k + 1), n)
        descent = -scatter_to_points(n, cells, gradient)
        descent[on_boundary] = tangential(grid, points[on_boundary], descent[on_boundary])
        # a Newton-like scale: the cost of a node's cells changes by about its own size over an edge length
        descent *= (0.5 * length ** 2 * degree / np.maximum(current, 1e-300))[:, None]
        descent[~np.isfinite(descent).all(axis=1)] = 0.0
        step = np.linalg.norm(descent, axis=1)
        descent *= np.minimum(1.0, MAX_MOVE * length / np.maximum(step, 1e-300))[:, None]

        off_surface = np.zeros(n, bool)
        off_surface[on_boundary] = np.abs(grid.evaluate(points[on_boundary])) > SURFACE_TOLERANCE * length
        limit = np.where(off_surface, np.inf, current)
        best_cost, best_move = limit.copy(), np.zeros_like(points)
        for fraction in STEP_FRACTIONS:
            move = fraction * descent
            move[on_boundary] = project_to_surface(grid, points[on_boundary] + move[on_boundary]) - points[on_boundary]
            # the cost of each node's cells when that node alone moves
            shift = move[cells]
            trial_volume = volume[:, None] + np.einsum("mij,mij->mi", volume_gradient, shift)
            trial_squares = squares[:, None] + np.einsum("mij,mij->mi", 2.0 * (k + 1) * centred + k * shift, shift)
            trial = np.bincount(corner_of, mean_ratio_cost(trial_volume.ravel(), trial_squares.ravel(), k)
                                ** SMOOTH_POWER, n)
            better = trial < best_cost
            best_cost[better], best_move[better] = trial[better], move[better]
        moving = np.isfinite(best_cost) & np.any(best_move != 0, axis=1)
        new = points.copy()
        new[moving] += best_move[moving]
        for _ in range(REVERT_ROUNDS):
            cost = inverse_mean_ratio(new[cells]) ** SMOOTH_POWER
            worse = np.bincount(corner_of, np.repeat(cost, k + 1), n) > limit
            worse[cells[~np.isfinite(cost)].ravel()] = True
            worse &= moving
            if not worse.any():
                break
            new[worse] = points[worse]
            moving &= ~worse
        else:
            new = points
        points = new
    report(progress, 1.0, "smoothing")
    return points


# --- the step ------------------------------------------------------------------------------------------------------

def peel(cells: np.ndarray, n_points: int, candidates: np.ndarray) -> np.ndarray:
    """``cells`` without those of the ``candidates`` (indices) that have two or more boundary facets.

    Such a cell lies on the surface (across a crease, or flat on a curved part): its vertices are boundary nodes
    before and after, and the boundary moves in by the cell's volume.  A cell whose removal would pinch the
    boundary or leave a node unused stays.
    """
    k = cells.shape[1] - 1
    _, inverse, counts = facet_table(cells)
    on_surface = (counts[inverse] == 1).reshape(-1, k + 1).sum(axis=1) >= 2
    removed = np.zeros(len(cells), bool)
    removed[candidates[on_surface[candidates]]] = True
    for _ in range(REVERT_ROUNDS):
        if not removed.any():
            break
        kept = cells[~removed]
        trouble = np.bincount(kept.ravel(), minlength=n_points) == 0
        for faces in non_manifold_faces(kept, n_points):
            trouble[faces.ravel()] = True
        restore = removed & trouble[cells].any(axis=1)
        if not restore.any():
            return kept
        removed &= ~restore
    return cells


def poor_cells(points: np.ndarray, cells: np.ndarray, min_angle: float, min_quality: float) -> np.ndarray:
    """The cells with an angle below ``min_angle`` (degrees; dihedral in 3D, interior in 2D) or a radius ratio
    below ``min_quality``."""
    return np.flatnonzero((smallest_angles(points, cells) < min_angle)
                          | (signed_radius_ratio(points, cells) < min_quality))


def remove_slivers(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, min_angle: float,
                   min_quality: float, progress: ProgressCallback = None) -> list:
    """Rounds of :func:`flip` and :func:`smooth` until no cell is poor (:func:`poor_cells`).

    After a round's smoothing, the poor cells that lie on the surface are peeled (:func:`peel`).  At least two
    rounds (the second gains from the first's flips), at most ``SLIVER_ROUNDS``; they stop once no cell is poor
    and the mean radius ratio no longer rises by ``MEAN_GAIN``.

    Returns
    -------
    list of (points, cells), the state after each round
    """
    states = []
    mean = signed_radius_ratio(points, cells).mean()
    for round_ in range(SLIVER_ROUNDS):
        cells = flip(points, cells, progress=sub_progress(progress, round_ / SLIVER_ROUNDS,
                                                          (round_ + 0.2) / SLIVER_ROUNDS))
        points = smooth(grid, points, cells, SMOOTH_ITERATIONS,
                        sub_progress(progress, (round_ + 0.2) / SLIVER_ROUNDS, (round_ + 1) / SLIVER_ROUNDS))
        poor = poor_cells(points, cells, min_angle, min_quality)
        if len(poor):
            cells = peel(cells, len(points), poor)
            poor = poor_cells(points, cells, min_angle, min_quality)
        states.append((points, cells))
        previous, mean = mean, signed_radius_ratio(points, cells).mean()
        report(progress, (round_ + 1) / SLIVER_ROUNDS,
               f"sliver removal round {round_ + 1}: mean radius ratio {mean:.4f}, {len(poor)} cells with an angle "
               f"below {min_angle:g} degrees or a radius ratio below {min_quality:g}")
        if round_ >= 1 and len(poor) == 0 and mean < previous + MEAN_GAIN:
            break
    return states


def _defects(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters, tolerance: float) -> tuple:
    """What keeps ``mesh`` from the goal: the number of poor cells, of boundary nodes off f = 0, and the mean
    radius ratio."""
    poor = len(poor_cells(mesh.points, mesh.cells, parameters.min_dihedral, parameters.min_quality))
    off = len(off_surface_nodes(grid, mesh.points, mesh.cells, tolerance))
    return poor, off, float(signed_radius_ratio(mesh.points, mesh.cells).mean())


def topology(mesh: Mesh) -> tuple:
    """(boundary components, boundary Euler characteristic) of a valid mesh: what optimising must not change."""
    return count_boundary_components(mesh), boundary_euler_characteristic(mesh)


def optimize_mesh(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters = OptimizeParameters(),
                  progress: ProgressCallback = None) -> Mesh:
    """Relax the nodes, remove the slivers and keep the boundary on f = 0 (see the module's docstring).

    Parameters
    ----------
    grid : the implicit function f on the grid I (f > 0 inside)
    mesh : a valid mesh of {f > 0}, triangles (2D) or tetrahedra (3D), positively oriented, as from
        :func:`bitemesh.core.pipeline.mesh_from_grid`; it is not modified
    parameters : the relaxation's iteration bound and the bounds (angle, radius ratio) of the sliver removal
    progress : callable(fraction, message), optional; the messages report the mean radius ratio as it converges
        and, last, what remains (poor cells, boundary nodes off f = 0); it may raise
        :class:`~bitemesh.core.errors.Cancelled`

    Returns
    -------
    A valid mesh without cell data: of the states met (the input, the relaxed mesh, the mesh after each round of
    sliver removal) the valid one with the input's :func:`topology` and the fewest poor cells (:func:`poor_cells`)
    plus boundary nodes off f = 0, then the highest mean radius ratio; the input's points and cells when nothing did
    better.
    Raises :class:`MeshingError` when no state, the input included, is a valid domain.
    """
    if mesh.dim != grid.dim:
        raise InvalidInputError(f"mesh is {mesh.dim}D but grid is {grid.dim}D; optimise a mesh of the same dimension")
    if len(mesh.cells) == 0:
        raise InvalidInputError("mesh has no cells: there is nothing to optimise")
    start = Mesh(np.array(mesh.points, dtype=np.float64), np.array(mesh.cells, dtype=np.int64))
    tolerance = SURFACE_TOLERANCE * mean_edge_length(start.points, start.cells)
    states = [start]
    shape = topology(start)
    points, cells = start.points, start.cells
    if parameters.iterations:
        try:
            points, cells, _ = relax(grid, points, cells, parameters.iterations,
                                     progress=sub_progress(progress, 0.0, 0.5))
            if topology(Mesh(points, cells)) != shape:
                raise MeshingError("the relaxed boundary has (components, Euler characteristic) "
                                   f"{topology(Mesh(points, cells))}, the input {shape}")
            states.append(Mesh(points, cells))
        except MeshingError as error:  # the relaxed nodes do not carve into the input's valid domain
            report(progress, 0.5, f"relaxation abandoned ({error}); removing the input's slivers")
            points, cells = start.points, start.cells
    states += [Mesh(p, c) for p, c in remove_slivers(grid, points, cells, parameters.min_dihedral,
                                                     parameters.min_quality, sub_progress(progress, 0.5, 0.95))]
    report(progress, 0.95, "checking the result")
    defects = [_defects(grid, state, parameters, tolerance) for state in states]
    for index in sorted(range(len(states)), key=lambda i: (defects[i][0] + defects[i][1], -defects[i][2], -i)):
        if not check_valid_domain(states[index]) and topology(states[index]) == shape:
            poor, off, mean = defects[index]
            outcome = "optimised" if index else "kept the input (nothing did better)"
            report(progress, 1.0, f"{outcome}: mean radius ratio {mean:.4f}; remain {poor} cells with an angle "
                                  f"below {parameters.min_dihedral:g} degrees or a radius ratio below "
                                  f"{parameters.min_quality:g}, {off} boundary nodes off f = 0")
            if poor:
                warn_missed_bounds(states[index], parameters, poor)
            return states[index]
    raise MeshingError("the mesh is not a valid domain, and optimising did not make it one: "
                       + "; ".join(check_valid_domain(start)))


def warn_missed_bounds(mesh: Mesh, parameters: OptimizeParameters, poor: int) -> None:
    """A :class:`BitemeshWarning` with the figures: the optimised mesh still has ``poor`` cells below its bounds."""
    angle = float(smallest_angles(mesh.points, mesh.cells).min())
    quality = float(signed_radius_ratio(mesh.points, mesh.cells).min())
    warnings.warn(
        f"the optimiser could not meet its bounds: {poor} of {len(mesh.cells)} cells remain below min_dihedral = "
        f"{parameters.min_dihedral:g} degrees or min_quality = {parameters.min_quality:g} (smallest angle "
        f"{angle:.1f} degrees, smallest radius ratio {quality:.3f}); walls only a few cells thick leave no room to "
        "repair them: lower radius (or raise cells) to put more cells across the thinnest wall", BitemeshWarning,
        stacklevel=2)
