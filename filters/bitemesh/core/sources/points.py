"""Scattered points to a mesh: the points source on the one meshing spine (:mod:`bitemesh.core.steps.spine`).

``run`` meshes points with one parameter dataclass per step (``bitemesh.mesh`` is the front door that calls it);
``points_to_implicit`` samples their f on the grid I as the run lays it out.
"""
from __future__ import annotations

import logging
from functools import partial

import numpy as np

from ..errors import InvalidInputError, check_points
from ..grid.sampled import ImplicitGrid
from ..implicit.mpu import MIN_POINTS
from ..implicit.fit import fit_implicit
from ..implicit.normals import disagreeing_normals
from ..parameters import (BitingParameters, FidelityParameters, ImplicitParameters, OptimizeParameters,
                          SpuriousParameters)
from ..implicit.samples import (PLANE_NEIGHBOURS, beyond_slices, contour_gap, find_outliers, near_duplicates,
                                noise_level, sample_spacing)
from ..progress import ProgressCallback, sub_progress
from ..steps.spine import MeshingResult, check_grid, check_memory, check_spacing, grid_for_source, mesh_source, timed
from .source import Frame, Source

logger = logging.getLogger("bitemesh")


def points_source(points, normals=None, implicit: ImplicitParameters = ImplicitParameters(),
                  progress: ProgressCallback = None, biting: BitingParameters | None = None,
                  slices=None) -> Source:
    """Scattered points as a :class:`Source`: outliers dropped (unless ``implicit.outliers`` is "keep"), the points
    centred and scaled to unit size (:meth:`Frame.around`), f fitted there (MPU or RBF), and the samples' spacing
    and noise measured for the fidelity check.

    Parameters
    ----------
    points : (n, k) float64, input units; normals : (n, k) float64 outward normals, or None to estimate them
    implicit : method, error_bound (input units) and outliers of :class:`ImplicitParameters`
    biting : when given with a radius (or ``implicit`` with a grid spacing), the grid I they imply is checked
        against the data and the memory before the fit (a refusal then comes in a moment, not after the fit)
    slices : (n,) int, the slice (contour) each point was traced on, or None for points sampled all over the
        surface: the gap between slices bounds how far the mesh boundary may lie from the points, and the caps
        beyond the first and the last of parallel slices are left out of that measure
    """
    points = _enough_points(points)
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float64)
        if normals.shape != points.shape:
            raise InvalidInputError(f"normals must have the shape of points {points.shape}, got {normals.shape}")
    if slices is not None:
        slices = np.asarray(slices)
        if slices.shape != (len(points),) or slices.dtype.kind not in "iu":
            raise InvalidInputError(f"slices must hold one integer per point ({len(points)}), got shape "
                                    f"{slices.shape} of {slices.dtype}")
    notes = []
    first = near_duplicates(points)
    if (first != np.arange(len(points))).any():
        kept = first == np.arange(len(points))   # the first of each group, with its normal
        normals = None if normals is None else normals[kept]
        repeated = len(np.unique(first[~kept]))
        notes.append(f"merged {len(points) - int(kept.sum())} near-duplicate point(s) into the {repeated} they repeat "
                     f"(within 0.1 % of the spacing, as scans merged from several passes repeat points); "
                     f"{int(kept.sum())} points remain")
        logger.info(notes[-1])
        points, slices = points[kept], None if slices is None else slices[kept]
        points = _enough_points(points)
    if implicit.outliers == "drop" and len(points) > 2 * PLANE_NEIGHBOURS:
        outlier = find_outliers(points)
        if outlier.any():
            points = points[~outlier]
            normals = None if normals is None else normals[~outlier]
            slices = None if slices is None else slices[~outlier]
            notes.append(f"dropped {int(outlier.sum())} outliers of {len(outlier)} points ({outlier.mean():.1%}): "
                         "far from the others or off the surface their neighbours sample (outliers='keep' keeps "
                         "them)")
            logger.info(notes[-1])
    frame = Frame.around(points)
    local = frame.to_local(points)
    box = Source(None, local.min(axis=0), local.max(axis=0), frame)
    check_spacing(box, implicit)
    if biting is not None and biting.radius is not None:
        check_grid(box, biting.radius / frame.scale, implicit, biting)
    elif biting is not None and implicit.grid_spacing is not None:
        check_memory(box, None, implicit, biting)
    error_bound = None if implicit.error_bound is None else implicit.error_bound / frame.scale
    function = fit_implicit(local, normals, method=implicit.method, error_bound=error_bound, progress=progress)
    distinct = np.unique(local, axis=0)
    gap, caps = 2 * sample_spacing(distinct), None
    if slices is not None:
        gap = max(gap, contour_gap(local, slices))
        caps = beyond_slices(local, slices)
    return Source(function, local.min(axis=0), local.max(axis=0), frame, samples=local, noise=noise_level(distinct),
                  gap=gap, open_boundary=caps, notes=tuple(notes), one_fit=slices is None,
                  suspects=partial(_suspects, points, normals, implicit.outliers == "keep"))


def _suspects(points: np.ndarray, normals, outliers_kept: bool) -> str:
    """What in the (n, k) samples may make a mesh leave them (:attr:`Source.suspects`, asked on a refusal only):
    outliers kept on request, given normals that disagree with their surface
    (:func:`~bitemesh.core.implicit.normals.disagreeing_normals`)."""
    outlier = find_outliers(points) if outliers_kept and len(points) > 2 * PLANE_NEIGHBOURS else np.zeros(0, bool)
    if outlier.any():
        return (f"{int(outlier.sum())} of the input points ({outlier.mean():.1%}) are outliers (far from the others "
                "or off the surface their neighbours sample), kept as outliers = 'keep' asks; leave outliers at "
                "'drop' (the default; --outliers drop) to drop them")
    return "" if normals is None else disagreeing_normals(points, normals)


def _enough_points(points) -> np.ndarray:
    """``points`` checked (:func:`check_points`) and at least :data:`MIN_POINTS` of them."""
    points = check_points(points)
    if len(points) < MIN_POINTS:
        raise InvalidInputError(f"points: need at least {MIN_POINTS} points, got {len(points)}")
    return points


def points_to_implicit(points, normals=None, *, method: str = "auto", error_bound=None, grid_spacing=None,
                       margin=None, max_memory_mb: float = 4096, outliers: str = "drop", radius=None,
                       cells: int | None = None, progress: ProgressCallback = None) -> ImplicitGrid:
    """Reconstruct f from scattered points (:func:`points_source`) and sample it on the grid I, laid out as
    :func:`run` lays it out (:func:`~bitemesh.core.steps.spine.grid_for_source`).

    Parameters
    ----------
    points, normals : as for :func:`points_source`; method, error_bound, outliers : of :class:`ImplicitParameters`
    grid_spacing : float, input units; default R / 4 (at least 1/40 of the data's longest side)
    margin : float, input units, grid extent beyond the bounding box; default 3 x grid_spacing
    max_memory_mb : float, MiB the grid may take; a larger grid is refused before fitting
    radius, cells : R the grid is laid out for (input units), or chosen for about ``cells`` cells
    progress : callable(fraction, message), optional

    Returns
    -------
    ImplicitGrid over the points' box and a margin, f > 0 inside, input units
    """
    implicit = ImplicitParameters(method=method, error_bound=error_bound, grid_spacing=grid_spacing, margin=margin,
                                  max_memory_mb=max_memory_mb, outliers=outliers)
    biting = BitingParameters(radius=radius, cells=cells)
    source = points_source(points, normals, implicit, sub_progress(progress, 0.0, 0.4), biting)
    grid = grid_for_source(source, implicit, biting, sub_progress(progress, 0.4, 1.0))[0]
    return source.frame.grid_to_user(grid)


def run(points, normals=None, implicit: ImplicitParameters = ImplicitParameters(),
        biting: BitingParameters = BitingParameters(), spurious: SpuriousParameters = SpuriousParameters(),
        progress: ProgressCallback = None, optimize: OptimizeParameters = OptimizeParameters(),
        fidelity: FidelityParameters = FidelityParameters(), slices=None) -> MeshingResult:
    """Every step of the method on scattered points, with the parameters of each step (the MeshOptimizer runs when
    ``optimize.optimize`` is 1): :func:`points_source`, then the spine (:func:`~bitemesh.core.steps.spine.mesh_source`).
    ``slices`` (optional): the contour each point was traced on, see :func:`points_source`."""
    seconds = {}
    with timed(seconds, "implicit fit"):
        source = points_source(points, normals, implicit, sub_progress(progress, 0.0, 0.3), biting, slices)
    return mesh_source(source, implicit, biting, spurious, optimize, sub_progress(progress, 0.3, 1.0), seconds,
                       fidelity)
