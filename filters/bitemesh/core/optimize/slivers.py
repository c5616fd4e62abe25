"""Sliver removal, the second step of the MeshOptimizer (:mod:`bitemesh.core.optimize.optimizer`): rounds of flips
(:mod:`bitemesh.core.optimize.flips`), which replace the cells around an interior edge (edge removal: 3-2, 4-4, 5-6 ...
flips) or on both sides of an interior facet (2-3 flips; 2-2 in 2D) when that raises the worst radius ratio among
them, then of smoothing (:func:`bitemesh.core.optimize.relax.smooth`).  A poor cell left (an angle below
``min_dihedral`` or a radius ratio below ``min_quality``, :func:`poor_cells`) that lies on the surface is peeled
(:func:`peel`); from the second round, one flat against it loses a boundary edge to a collapse
(:mod:`bitemesh.core.optimize.collapse`).  The rounds end when no cell is poor (within ``SLIVER_ROUNDS``); a last
few passes of peel and collapse follow.
"""
from __future__ import annotations

import numpy as np

from ..mesh.quality import signed_radius_ratio
from .measures import smallest_angles
from .collapse import collapse_flat_cells
from .flips import flip
from ..grid.sampled import ImplicitGrid
from ..progress import ProgressCallback, report, sub_progress
from .relax import MEAN_GAIN, REVERT_ROUNDS, smooth
from ..mesh.topology import CellComplex, single_facets

#: rounds of flips and smoothing, and the smoothing iterations in each round.
SLIVER_ROUNDS = 4
SMOOTH_ITERATIONS = 3
#: passes of peel and collapse after the last round, while they remove cells.
FINAL_PASSES = 3


def peel(cells: np.ndarray, n_points: int, candidates: np.ndarray) -> np.ndarray:
    """``cells`` without those of the ``candidates`` (indices) that have two or more boundary facets.

    Such a cell lies on the surface (across a crease, or flat on a curved part): its vertices are boundary nodes
    before and after, and the boundary moves in by the cell's volume.  A cell whose removal would pinch the
    boundary or leave a node unused stays.
    """
    on_surface = single_facets(cells).sum(axis=1) >= 2
    removed = np.zeros(len(cells), bool)
    removed[candidates[on_surface[candidates]]] = True
    complex_ = CellComplex(cells, n_points) if removed.any() else None
    for _ in range(REVERT_ROUNDS):
        if not removed.any():
            break
        kept = cells[~removed]
        trouble = np.bincount(kept.ravel(), minlength=n_points) == 0
        for faces in complex_.non_manifold_faces(~removed):
            trouble[faces.ravel()] = True
        restore = removed & trouble[cells].any(axis=1)
        if not restore.any():
            return kept
        removed &= ~restore
    return cells


def poor_cells(points: np.ndarray, cells: np.ndarray, min_angle: float, min_quality: float,
               quality: np.ndarray | None = None) -> np.ndarray:
    """The cells with an angle below ``min_angle`` (degrees; dihedral in 3D, interior in 2D) or a radius ratio
    below ``min_quality``; ``quality``: their :func:`signed_radius_ratio`, when already known."""
    quality = signed_radius_ratio(points, cells) if quality is None else quality
    return np.flatnonzero((smallest_angles(points, cells) < min_angle) | (quality < min_quality))


def remove_slivers(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, min_angle: float,
                   min_quality: float, progress: ProgressCallback = None) -> list:
    """Rounds of :func:`flip` and :func:`smooth` until no cell is poor (:func:`poor_cells`).

    After a round's smoothing, the poor cells that lie on the surface are peeled (:func:`peel`), and from the
    second round those flat against it collapse (:func:`collapse_flat_cells`).  At least two
    rounds (the second gains from the first's flips), at most ``SLIVER_ROUNDS``; they stop once no cell is poor
    and the mean radius ratio no longer rises by ``MEAN_GAIN``.  Then up to ``FINAL_PASSES`` passes of peel and
    collapse take what the last flips and smoothing left on the surface (cine frame 6: a cap of 1.4 degrees with
    three facets on the surface; its smallest angle 1.4 -> 7.8 degrees).

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
        points, cells, quality, poor = _off_the_surface(points, cells, min_angle, min_quality, collapse=round_ >= 1)
        states.append((points, cells))
        previous, mean = mean, quality.mean()
        report(progress, (round_ + 1) / SLIVER_ROUNDS,
               f"sliver removal round {round_ + 1}: mean radius ratio {mean:.4f}, {len(poor)} cells with an angle "
               f"below {min_angle:g} degrees or a radius ratio below {min_quality:g}")
        if round_ >= 1 and len(poor) == 0 and mean < previous + MEAN_GAIN:
            break
    for _ in range(FINAL_PASSES):   # what the last flips and smoothing left on the surface, no node moved
        if not len(poor):
            break
        before = len(cells)
        points, cells, quality, poor = _off_the_surface(points, cells, min_angle, min_quality, collapse=True)
        if len(cells) == before:
            break
        states.append((points, cells))
    return states


def _off_the_surface(points, cells, min_angle: float, min_quality: float, collapse: bool) -> tuple:
    """The poor cells on the surface peeled (:func:`peel`), then, with ``collapse``, those flat against it collapsed
    (:func:`collapse_flat_cells`): (points, cells, their radius ratios, the poor cells left)."""
    quality = signed_radius_ratio(points, cells)
    poor = poor_cells(points, cells, min_angle, min_quality, quality)
    peeled = peel(cells, len(points), poor) if len(poor) else cells
    if peeled is not cells:
        cells, quality = peeled, signed_radius_ratio(points, peeled)
        poor = poor_cells(points, cells, min_angle, min_quality, quality)
    if collapse and len(poor):   # what a round of flips and smoothing left flat against the surface
        points, collapsed = collapse_flat_cells(points, cells, poor)
        if collapsed is not cells:
            cells, quality = collapsed, signed_radius_ratio(points, collapsed)
            poor = poor_cells(points, cells, min_angle, min_quality, quality)
    return points, cells, quality, poor
