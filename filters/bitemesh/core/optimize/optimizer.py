"""Mesh optimisation: the relaxation and the sliver removal that the paper leaves to future work (sections 5-6).

1. Boundary nodes: every node on the boundary of the mesh goes onto f = 0 (Newton steps along grad f,
   :meth:`bitemesh.core.grid.sampled.SampledGrid.project`) and every later move keeps it there.
2. Relaxation (:func:`bitemesh.core.optimize.relax.relax`): optimal Delaunay triangulation (ODT) smoothing, Alliez et
   al. 2005.  Each interior node moves to the volume-weighted mean of the circumcentres of its cells, each boundary
   node towards the area-weighted mean of the centroids of its boundary facets, along the surface and back onto
   f = 0 (a move that would invert a cell is taken back); then Lawson's flips towards the Delaunay triangulation
   (:mod:`bitemesh.core.optimize.delaunay_flips`) update the cells locally, in place of a new triangulation of all the
   nodes, until the mean radius ratio stops rising.
3. Sliver removal (:func:`bitemesh.core.optimize.slivers.remove_slivers`): rounds of flips
   (:mod:`bitemesh.core.optimize.flips`), which replace the cells around an interior edge (edge removal: 3-2, 4-4, 5-6
   ... flips) or on both sides of an interior facet (2-3 flips; 2-2 in 2D) when that raises the worst radius ratio
   among them, then of smoothing (:func:`bitemesh.core.optimize.relax.smooth`), which moves the nodes down sum over the
   cells of (1 / mean ratio)^2 (Knupp's inverse mean ratio, infinite for a flat cell) with the boundary nodes sliding
   on f = 0.  A poor cell left (an angle below ``min_dihedral`` or a radius ratio below ``min_quality``) that lies on
   the surface is peeled (:func:`bitemesh.core.optimize.slivers.peel`); from the second round, one that lies flat
   against it, every node on the boundary (where the surface triangulation folds), loses a boundary edge to a collapse
   (:mod:`bitemesh.core.optimize.collapse`).  The rounds end when no cell is poor (within ``SLIVER_ROUNDS``).
4. Nothing turns a valid mesh into an invalid one: flips only replace cells inside the domain and smoothing keeps
   every cell positive; :func:`bitemesh.core.mesh.validity.check_valid_domain` then judges the states met, and the best
   valid one is returned (the input itself when nothing did better).  Nor does anything change its topology (the
   boundary's components and Euler characteristic, :func:`topology`): the relaxation and the flips keep the
   boundary facets, a collapse is checked around it, and a state whose topology differs all the same is abandoned
   (the sliver removal then starts from the input).

The nodes are the biting's, only moved (but for the few collapsed away at folds): the node spacing stays uniform.
Everything is deterministic.  Measured on the sphere of 10,000 cells of ``benchmarks/peers.py``: mean radius ratio
0.81 -> 0.90, smallest dihedral angle 0.8 -> 31 degrees, edge-length CV 0.17 -> 0.13, in 0.4 s; on the two-cavity
heart of 136,000 cells 10 s (19 s with the passes of independent Delaunay flips that Lawson's replaced, 27 s with a
new Delaunay triangulation per iteration before them), with the same quality.

This module runs the steps and picks the state returned (:func:`optimize_mesh`); the relaxation and the smoothing
live in :mod:`bitemesh.core.optimize.relax`, the sliver removal in :mod:`bitemesh.core.optimize.slivers`, and their
names are re-exported here (``from bitemesh.core.optimize.optimizer import relax, smooth, peel`` works as before).
"""
from __future__ import annotations

import warnings

import numpy as np

from .measures import boundary_nodes, mean_edge_length, off_surface_nodes, smallest_angles
from ..mesh.quality import signed_radius_ratio
from ..errors import BitemeshWarning, InvalidInputError, MeshingError
from ..grid.sampled import ImplicitGrid
from ..mesh.simplicial import Mesh
from ..parameters import OptimizeParameters
from ..progress import ProgressCallback, report, sub_progress
from .relax import (SURFACE_TOLERANCE, relax)
from .slivers import poor_cells, remove_slivers
from ..mesh.validity import boundary_euler_characteristic, check_valid_domain, count_boundary_components


#: a cell whose nodes all lie on the boundary is flat against one side of the surface when the unit normal
#: (grad f) at each node is within acos(FLAT_AGREEMENT) = 60 degrees of their mean; across a wall they oppose.
FLAT_AGREEMENT = 0.5


def _defects(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters, tolerance: float) -> tuple:
    """What keeps ``mesh`` from the goal: the number of poor cells, of boundary nodes off f = 0, and the mean
    radius ratio."""
    quality = signed_radius_ratio(mesh.points, mesh.cells)
    poor = len(poor_cells(mesh.points, mesh.cells, parameters.min_dihedral, parameters.min_quality, quality))
    off = len(off_surface_nodes(grid, mesh.points, mesh.cells, tolerance))
    return poor, off, float(quality.mean())


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
        :func:`bitemesh.core.sources.points.mesh_from_grid`; it is not modified
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
        except MeshingError as error:  # the relaxed boundary is not the input's
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
                warn_missed_bounds(grid, states[index], parameters, poor)
            return states[index]
    raise MeshingError("the mesh is not a valid domain, and optimising did not make it one: "
                       + "; ".join(check_valid_domain(start)))


def warn_missed_bounds(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters, poor: int) -> None:
    """A :class:`BitemeshWarning` with the figures: the optimised mesh still has ``poor`` cells below its bounds,
    and where they lie (flat against the surface, or across a wall a few cells thick), each with the hint that
    works there."""
    cells = mesh.cells[poor_cells(mesh.points, mesh.cells, parameters.min_dihedral, parameters.min_quality)]
    normals = grid.gradient(mesh.points[cells].reshape(-1, mesh.dim)).reshape(*cells.shape, mesh.dim)
    normals /= np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-300)
    mean = normals.sum(axis=1)
    mean /= np.maximum(np.linalg.norm(mean, axis=1, keepdims=True), 1e-300)
    facing_one_way = np.einsum("ckd,cd->ck", normals, mean).min(axis=1) > FLAT_AGREEMENT
    near_flat = np.zeros(len(mesh.points), bool)   # the nodes of the cells flat against one side of the surface
    near_flat[cells[boundary_nodes(mesh.cells, len(mesh.points))[cells].all(axis=1) & facing_one_way]] = True
    flat = int(near_flat[cells].any(axis=1).sum())   # those cells and the poor cells beside them
    angle = float(smallest_angles(mesh.points, mesh.cells).min())
    quality = float(signed_radius_ratio(mesh.points, mesh.cells).min())
    where = []
    if flat:
        where.append(f"{flat} {_lie(flat)} flat against the surface, every node on the boundary, or beside such a "
                     "cell (where the surface triangulation folds over a curved or creased part and no edge "
                     "collapse helped): another seed places the nodes differently")
    if len(cells) > flat:
        where.append(f"{len(cells) - flat} {_lie(len(cells) - flat)} elsewhere: across walls only a few cells thick, "
                     "which leave no room to repair them (lower radius, or raise cells, to put more cells across the "
                     "thinnest wall), or below bounds stricter than uniform cells allow (lower min_dihedral or "
                     "min_quality)")
    warnings.warn(
        f"the optimiser could not meet its bounds: {poor} of {len(mesh.cells)} cells remain below min_dihedral = "
        f"{parameters.min_dihedral:g} degrees or min_quality = {parameters.min_quality:g} (smallest angle "
        f"{angle:.1f} degrees, smallest radius ratio {quality:.3f}); " + "; ".join(where), BitemeshWarning,
        stacklevel=2)


def _lie(count: int) -> str:
    return "lies" if count == 1 else "lie"
