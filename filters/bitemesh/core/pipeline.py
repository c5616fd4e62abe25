"""The whole method in one call: scattered points -> implicit f on a grid -> nodes -> Delaunay -> valid domain.

``mesh_from_points`` is the API most users want; ``mesh_from_grid`` meshes an implicit function already sampled
on a grid (an analytic shape, a label map's signed distance).
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from .biting import bite
from .delaunay import delaunay
from .domain import carve_domain
from .errors import check_number, check_points
from .grid import EXACT_WITHIN, ImplicitGrid, sample_function
from .implicit import fit_implicit
from .mesh import Mesh
from .optimize import optimize_mesh
from .parameters import (BitingParameters, ImplicitParameters, OptimizeParameters, SpuriousParameters,
                         optimize_parameters)
from .progress import ProgressCallback, report, sub_progress
from .quality import cell_quality

#: cells per unit measure x R^k of a biting mesh (measured on a sphere, a torus and a die: 5.1 to 5.7 in 3D).
CELLS_PER_VOLUME = {2: 2.3, 3: 5.4}
#: grid spacing h = R / GRID_PER_RADIUS when the grid spacing is not given.
GRID_PER_RADIUS = 4.0
#: nodes per axis of the coarse grid that measures the volume when R is chosen from a cell count.
COARSE_GRID_NODES = 64
#: the default grid has at least this many nodes along the data's longest side, whatever R.
MIN_GRID_NODES = 40


@dataclass(frozen=True, eq=False)
class MeshingResult:
    """What a run of the pipeline produced.

    Attributes
    ----------
    mesh : the valid mesh, with the quality arrays as cell data
    implicit : f on the grid I
    nodes : (n, k) float64, every node the biting placed (the mesh keeps those its cells use)
    radius : R used (input units)
    seconds : step name -> wall-clock seconds
    """

    mesh: Mesh
    implicit: ImplicitGrid
    nodes: np.ndarray
    radius: float
    seconds: dict = field(default_factory=dict)


def radius_for_cells(measure: float, cells: int, dim: int) -> float:
    """R that gives about ``cells`` cells in a domain of area (2D) or volume (3D) ``measure``."""
    return float((CELLS_PER_VOLUME[dim] * measure / cells) ** (1.0 / dim))


@contextmanager
def timed(seconds: dict, name: str):
    """Add the wall-clock seconds of the ``with`` block to ``seconds[name]``."""
    clock = time.perf_counter()
    yield
    seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - clock


def mesh_from_grid(grid: ImplicitGrid, biting: BitingParameters, spurious: SpuriousParameters = SpuriousParameters(),
                   progress: ProgressCallback = None, seconds: dict | None = None,
                   optimize: OptimizeParameters | None = None) -> MeshingResult:
    """Mesh {f > 0} of a sampled implicit function; R is ``biting.radius`` or chosen for ``biting.cells`` cells.

    With ``optimize``, the MeshOptimizer step (relaxation, sliver removal) runs on the valid domain.
    """
    seconds = {} if seconds is None else seconds
    radius = biting.radius or radius_for_cells(grid.inside_volume(), biting.cells, grid.dim)
    carved = 0.9 if optimize is None else 0.6
    with timed(seconds, "biting"):
        nodes = bite(grid, radius, order=biting.order, seed=biting.seed, progress=sub_progress(progress, 0, 0.3))
    with timed(seconds, "delaunay"):
        cells = delaunay(nodes)
    report(progress, 0.45, "delaunay")
    with timed(seconds, "spurious cells"):
        mesh = carve_domain(grid, nodes, cells, spurious, progress=sub_progress(progress, 0.45, carved))
    if optimize is not None:
        with timed(seconds, "optimize"):
            mesh = optimize_mesh(grid, mesh, optimize, progress=sub_progress(progress, carved, 0.97))
    with timed(seconds, "quality"):
        mesh = mesh.with_cell_data(**cell_quality(mesh))
    report(progress, 1.0, "quality")
    return MeshingResult(mesh=mesh, implicit=grid, nodes=nodes, radius=radius, seconds=seconds)


def implicit_grid(function, lower, upper, implicit: ImplicitParameters, radius: float | None, cells: int,
                  progress: ProgressCallback = None):
    """Sample ``function`` on the grid I, choosing R first (from a coarse grid's volume) when it is not given.

    Returns the grid and R.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    size = float(np.max(upper - lower))
    if radius is None:
        coarse = max(size / COARSE_GRID_NODES, implicit.grid_spacing or 0.0)
        volume = sample_function(function, lower, upper, coarse, margin=2 * coarse,
                                 max_memory_mb=implicit.max_memory_mb).inside_volume()
        radius = radius_for_cells(volume, cells, len(lower))
    check_number(radius, "radius", low=0, low_open=True, high=size,
                 hint="radius is R, the node spacing; it cannot exceed the size of the data's bounding box")
    spacing = implicit.grid_spacing or min(radius / GRID_PER_RADIUS, size / MIN_GRID_NODES)
    margin = implicit.margin if implicit.margin is not None else 3 * spacing
    grid = sample_function(function, lower, upper, spacing, margin=margin, max_memory_mb=implicit.max_memory_mb,
                           exact_within=EXACT_WITHIN * spacing, progress=progress)
    return grid, radius


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
    with timed(seconds, "implicit sampling"):
        grid, radius = implicit_grid(function, points.min(axis=0), points.max(axis=0), implicit, biting.radius,
                                     biting.cells, progress=sub_progress(progress, 0.3, 0.5))
    fixed = BitingParameters(radius=radius, cells=biting.cells, order=biting.order, seed=biting.seed)
    return mesh_from_grid(grid, fixed, spurious, sub_progress(progress, 0.5, 1.0), seconds, optimize)


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
