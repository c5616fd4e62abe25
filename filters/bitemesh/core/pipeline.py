"""Scattered points to a mesh: the points source on the one meshing spine (:mod:`bitemesh.core.spine`).

``mesh_from_points`` is the API most users want; ``run`` returns the whole :class:`MeshingResult`;
``mesh_from_grid`` meshes an implicit function already sampled on a grid (an analytic shape).
"""
from __future__ import annotations

from .errors import check_points
from .implicit import fit_implicit
from .mesh import Mesh
from .parameters import (BitingParameters, ImplicitParameters, OptimizeParameters, SpuriousParameters,
                         optimize_parameters)
from .progress import ProgressCallback, sub_progress
from .spine import (CELLS_PER_VOLUME, COARSE_GRID_NODES, GRID_PER_RADIUS, MIN_GRID_NODES,  # noqa: F401 (re-exported)
                    Frame, MeshingResult, Source, mesh_from_grid, mesh_source, radius_for_cells, timed)


def run(points, normals=None, implicit: ImplicitParameters = ImplicitParameters(),
        biting: BitingParameters = BitingParameters(), spurious: SpuriousParameters = SpuriousParameters(),
        progress: ProgressCallback = None, optimize: OptimizeParameters | None = None) -> MeshingResult:
    """Every step of the method on scattered points, with the parameters of each step (``optimize``: None skips
    the MeshOptimizer)."""
    points = check_points(points)
    seconds = {}
    with timed(seconds, "implicit fit"):
        function = fit_implicit(points, normals, method=implicit.method, error_bound=implicit.error_bound,
                                progress=sub_progress(progress, 0.0, 0.3))
    source = Source(function, points.min(axis=0), points.max(axis=0), Frame.identity(points.shape[1]),
                    samples=points)
    return mesh_source(source, implicit, biting, spurious, optimize, sub_progress(progress, 0.3, 1.0), seconds)


def mesh_from_points(points, normals=None, *, radius=None, cells=10000, method="mpu", error_bound=None,
                     grid_spacing=None, margin=None, max_memory_mb=4096.0, threshold=0.4, min_component=0.01,
                     order="boundary", seed=0, optimize=False, progress: ProgressCallback = None) -> Mesh:
    """A valid tetrahedral (triangular in 2D) mesh of the shape sampled by scattered points.

    Parameters
    ----------
    points : (n, 3) or (n, 2) float64, samples of the surface (input units)
    normals : (n, k) float64 outward normals, or None to estimate them
    radius : R, node spacing (input units); default: chosen for about ``cells`` cells
    optimize : True also runs the MeshOptimizer (relaxation, sliver removal) with its defaults, or give its
        OptimizeParameters
    The other parameters are those of :class:`ImplicitParameters`, :class:`BitingParameters` and
    :class:`SpuriousParameters`, with the same names.

    Returns
    -------
    Mesh with cell data RadiusRatio, MinDihedralAngle, MaxDihedralAngle and Volume.
    """
    return run(points, normals,
               ImplicitParameters(method=method, error_bound=error_bound, grid_spacing=grid_spacing, margin=margin,
                                  max_memory_mb=max_memory_mb),
               BitingParameters(radius=radius, cells=cells, order=order, seed=seed),
               SpuriousParameters(threshold=threshold, min_component=min_component), progress,
               optimize_parameters(optimize)).mesh
