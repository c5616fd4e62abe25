"""Moving the nodes of a valid mesh (the cells of the MeshOptimizer, :mod:`bitemesh.core.optimize.optimizer`): the
relaxation and the smoothing.  Boundary nodes stay on f = 0 (Newton steps along grad f,
:meth:`bitemesh.core.grid.sampled.SampledGrid.project`).

- Relaxation (:func:`relax`): optimal Delaunay triangulation (ODT) smoothing, Alliez et al. 2005.  Each interior
  node moves to the volume-weighted mean of the circumcentres of its cells, each boundary node towards the
  area-weighted mean of the centroids of its boundary facets, along the surface and back onto f = 0; then the
  cells are updated locally by flips towards the Delaunay triangulation (:mod:`bitemesh.core.optimize.delaunay_flips`)
  instead of a new triangulation of all the nodes, until the mean radius ratio stops rising.  The boundary facets
  and the nodes stay: the mesh stays a valid domain of the input's topology.
- Smoothing (:func:`smooth`, a step of the sliver removal, :mod:`bitemesh.core.optimize.slivers`): the nodes move down
  sum over the cells of (1 / mean ratio)^2 (Knupp's inverse mean ratio, infinite for a flat cell) with the boundary
  nodes sliding on f = 0; the cells stay as they are and every cell stays positive.
"""
from __future__ import annotations

import itertools

import numpy as np

from .measures import (boundary_nodes, inverse_mean_ratio, mean_edge_length, mean_ratio_cost, mean_ratio_terms,
                       node_cost_descent, node_trial_costs, scatter_to_points, tangential)
from ..mesh.quality import dot, signed_radius_ratio
from .delaunay_flips import FLAT_QUALITY, flip_to_delaunay
from ..grid.sampled import ImplicitGrid
from ..mesh.simplicial import circumspheres, facet_measures, signed_measures
from ..progress import ProgressCallback, report
from ..mesh.topology import boundary_facets

#: the relaxation, and the rounds of sliver removal once no cell is below the angle bound, stop when the mean
#: radius ratio has not risen by MEAN_GAIN over their last PATIENCE iterations (rounds: over the last one).
MEAN_GAIN = 2e-3
PATIENCE = 2
#: an interior node may come no closer to f = 0 than this fraction of the mean edge length.
INTERIOR_MARGIN = 0.3
#: smoothing: exponent p of the cost (1 / mean ratio)^p, longest move (x mean edge length), the step lengths tried.
SMOOTH_POWER = 2
MAX_MOVE = 0.2
STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.125)
#: rounds in which moves that made a shared cell worse are taken back (smoothing; after them, the moves of the
#: nodes around those still worse go back too), or in which peeled cells that pinched the boundary come back (peel,
#: :mod:`bitemesh.core.optimize.slivers`).
REVERT_ROUNDS = 10
#: a boundary node is on the surface when |f| there is below this fraction of the mean edge length.
SURFACE_TOLERANCE = 0.01


# --- relaxation ----------------------------------------------------------------------------------------------------

def odt_targets(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, margin: float,
                facets: np.ndarray | None = None) -> np.ndarray:
    """(n, k) where the ODT smoothing moves each node (Alliez et al. 2005, section 4); ``facets``: the boundary
    facets of ``cells`` (:func:`~bitemesh.core.mesh.topology.boundary_facets`) if known.

    Interior nodes: the volume-weighted mean of the circumcentres of their cells, pushed back to f = ``margin``
    when it lies closer to the surface.  Boundary nodes: the area-weighted mean of the centroids of their boundary
    facets, the move taken along the surface, then onto f = 0.  A node in no cell with volume stays.
    """
    n, k = points.shape
    centres = circumspheres(points, cells)[0]
    volume = np.abs(signed_measures(points, cells))
    usable = np.isfinite(centres).all(axis=1)
    weight = np.bincount(cells[usable].ravel(), np.repeat(volume[usable], k + 1), n)
    weighted = np.repeat((volume[usable, None] * centres[usable])[:, None], k + 1, axis=1)
    targets = points.copy()
    inner = np.flatnonzero(weight > 0)
    targets[inner] = scatter_to_points(n, cells[usable], weighted)[inner] / weight[inner, None]

    facets = boundary_facets(cells) if facets is None else facets
    corners = points[facets]
    area = facet_measures(corners)
    along = scatter_to_points(n, facets, np.repeat((area[:, None] * corners.mean(axis=1))[:, None], k, axis=1))
    along_weight = np.bincount(facets.ravel(), np.repeat(area, k), n)

    on_boundary = np.zeros(n, bool)
    on_boundary[facets.ravel()] = True
    inner = np.flatnonzero(~on_boundary)
    value = grid.evaluate(targets[inner])
    shallow = inner[value < margin]
    if len(shallow):
        gradient = grid.gradient(targets[shallow])
        squared = np.maximum(dot(gradient, gradient), 1e-12)
        targets[shallow] += ((margin - value[value < margin]) / squared)[:, None] * gradient
    outer = np.flatnonzero(on_boundary & (along_weight > 0))
    goal = along[outer] / along_weight[outer, None]
    targets[outer] = grid.project(points[outer] + tangential(grid, points[outer], goal - points[outer]))
    return targets


def relax(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
          progress: ProgressCallback = None):
    """ODT relaxation on the mesh's own cells: move the nodes (:func:`odt_targets`), take back the moves that
    would invert a cell, then update the cells locally by flips towards the Delaunay triangulation of the domain
    (:func:`bitemesh.core.optimize.delaunay_flips.flip_to_delaunay`); repeat.

    No full triangulation per iteration: flips replace cells inside the domain only, so the boundary facets, the
    nodes and the domain's topology stay those of the input (a wall thinner than a cell cannot open).  Stops after
    ``iterations`` moves, or when the mean radius ratio has not risen by ``MEAN_GAIN`` over ``PATIENCE``
    iterations.

    Returns
    -------
    points, cells : the relaxed valid mesh (the same nodes, moved)
    history : list of float, the mean radius ratio after each move
    """
    margin = INTERIOR_MARGIN * mean_edge_length(points, cells)
    facets, across = boundary_facets(cells), None   # the flips keep the boundary facets
    history = []
    for iteration in range(iterations):
        points = positive_moves(points, odt_targets(grid, points, cells, margin, facets), cells)
        cells, across = flip_to_delaunay(points, cells, across)
        history.append(float(signed_radius_ratio(points, cells).mean()))
        report(progress, (iteration + 1) / iterations,
               f"relaxation {iteration + 1}/{iterations}: mean radius ratio {history[-1]:.4f}")
        if len(history) > PATIENCE and max(history[-PATIENCE:]) < max(history[:-PATIENCE]) + MEAN_GAIN:
            break
    report(progress, 1.0, f"relaxation: {len(history)} iterations, mean radius ratio {history[-1]:.4f}"
           if history else "relaxation: no iteration")
    return points, cells, history


def positive_moves(points: np.ndarray, targets: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(n, k) the nodes moved to ``targets``, but for those of any cell the moves would invert or flatten (radius
    ratio at most ``FLAT_QUALITY``): they stay (round after round, as a cell may turn by the move of a node that
    stays in the next round)."""
    moved = targets.copy()
    moving = np.any(moved != points, axis=1)
    for _ in itertools.count():   # ends: each round takes back a move, and with none left the cells are the input's
        flat = signed_radius_ratio(moved, cells) <= FLAT_QUALITY
        back = np.zeros(len(points), bool)
        back[cells[flat].ravel()] = True
        back &= moving
        if not back.any():
            return moved
        moved[back] = points[back]
        moving &= ~back


# --- smoothing -----------------------------------------------------------------------------------------------------

def smooth(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
           progress: ProgressCallback = None) -> np.ndarray:
    """Move the nodes to lower sum over the cells of (1 / mean ratio)^p; the cells stay as they are.

    Each iteration takes, for every node, a step down the gradient of the cost of its cells (boundary nodes: its
    tangential part, then back onto f = 0): the best of ``STEP_FRACTIONS`` with the other nodes fixed (exact and
    cheap: a cell's volume is linear in one vertex).  All nodes move at once; a node whose cells then cost more
    than before, or one of which is inverted, goes back, round after round (after ``REVERT_ROUNDS``, with the
    nodes that share a cell with it: a chain of such nodes must not hold up the others).  A boundary node off f = 0
    goes onto it as soon as its cells stay positive there.

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
        best_move, limit = _best_moves(grid, points, cells, on_boundary, degree, length)
        moving = np.any(best_move != 0, axis=1)
        new = points.copy()
        new[moving] += best_move[moving]
        cost = inverse_mean_ratio(new, cells) ** SMOOTH_POWER
        for round_ in itertools.count():   # ends: each round takes back at least one move
            worse = np.bincount(corner_of, np.repeat(cost, k + 1), n) > limit
            worse[cells[~np.isfinite(cost)].ravel()] = True
            worse &= moving
            if not worse.any():
                break
            if round_ >= REVERT_ROUNDS:   # a chain of moves: those of the nodes around it go back too
                worse[cells[worse[cells].any(axis=1)].ravel()] = True
                worse &= moving
            new[worse] = points[worse]
            moving &= ~worse
            touched = np.flatnonzero(worse[cells].any(axis=1))  # only their cells change cost
            cost[touched] = inverse_mean_ratio(new, cells[touched]) ** SMOOTH_POWER
        points = new
    report(progress, 1.0, "smoothing")
    return points


def _best_moves(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, on_boundary: np.ndarray,
                degree: np.ndarray, length: float):
    """One smoothing iteration's choice, every other node fixed: each node's best move among ``STEP_FRACTIONS``
    of its descent (boundary nodes: tangential, then onto f = 0) and the cost its cells may not exceed.

    Returns
    -------
    move : (n, k) float64, zero where no step lowers the cost of the node's cells
    limit : (n,) float64, the cost of each node's cells before the move, which the moves may not raise (inf for a
        boundary node off f = 0: it goes onto f = 0 at any cost that keeps its cells positive)
    """
    n, k = points.shape
    # (m, k + 1, k) terms: freed on return, so that two iterations' never live at once
    volume, squares, volume_gradient, centred = mean_ratio_terms(points, cells)
    # not finite at the nodes of cells with no volume: they do not move
    current, descent = node_cost_descent(cells, mean_ratio_cost(volume, squares, k), squares, volume,
                                         volume_gradient, centred, n, SMOOTH_POWER)
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
    moves = [fraction * descent for fraction in STEP_FRACTIONS]
    start = points[on_boundary]  # the boundary nodes of every step length projected onto f = 0 at once
    ends = np.split(grid.project(np.concatenate([start + move[on_boundary] for move in moves])), len(moves))
    for move, end in zip(moves, ends):
        move[on_boundary] = end - start
        # the cost of each node's cells when that node alone moves
        trial = node_trial_costs(cells, volume, squares, volume_gradient, centred, move, n, SMOOTH_POWER)
        better = trial < best_cost
        best_cost[better], best_move[better] = trial[better], move[better]
    return best_move, limit
