"""The one meshing spine: each source of data hands over f in a local frame, and one function meshes it.

A source (scattered points: :func:`~bitemesh.core.sources.points.points_source`, labelled contours:
:func:`~bitemesh.core.labelled.labelled_source`, voxels: :func:`bitemesh.labelmap.label_grid_source`) returns a
:class:`~bitemesh.core.sources.source.Source`: the implicit function f (f > 0 inside) in a local frame, the box that
holds {f > 0}, the data's own surface samples, the map back to the user's coordinates and what the data implies for R
and the handles.  :func:`mesh_source` owns everything after that: choosing R, sampling the grid I, biting,
Delaunay, the spurious test and the repair, the MeshOptimizer, the quality, the fidelity check, and mapping the
mesh back.
"""
from __future__ import annotations

import logging
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Callable, Optional

import numpy as np

from .biting import bite
from .delaunay import delaunay
from .repair import carve_domain
from .retriangulate import relax_by_triangulation
from ..errors import BitemeshWarning, InvalidInputError, check_number, point_text
from ..mesh.betti import check_topology, enclosed_voids
from .fidelity import Fidelity
from .verdict import judge_fidelity
from ..grid.sampled import (BYTES_PER_NODE, EXACT_WITHIN, SampledGrid, available_memory_mb, grid_shape_unchecked,
                            inside_extents, sample_function)
from ..mesh.simplicial import Mesh
from ..optimize.optimizer import optimize_mesh
from ..parameters import (BitingParameters, FidelityParameters, ImplicitParameters, OptimizeParameters,
                          SpuriousParameters)
from ..progress import ProgressCallback, report, sub_progress
from ..mesh.quality import cell_quality
from ..sources.source import Frame, Source
from ..mesh.tags import component_tags

logger = logging.getLogger("bitemesh")

#: cells per unit measure x R^k of a biting mesh (measured on a sphere, a torus and a die: 5.1 to 5.7 in 3D; on the
#: 4-ball at R = 0.18 and the 5-ball at R = 0.45, relaxed: 21.7 and 125; the plain method's, 24.6 and 142).
CELLS_PER_VOLUME = {2: 2.3, 3: 5.4, 4: 22.0, 5: 125.0}
#: grid spacing h = R / GRID_PER_RADIUS when the grid spacing is not given.
GRID_PER_RADIUS = 4.0
#: nodes per axis of the coarse grid that measures the volume when R is chosen from a cell count (see a_side).
COARSE_GRID_NODES = 64
#: the default grid has at least this many nodes along the data's longest side, whatever R (see a_side).
MIN_GRID_NODES = 40
#: the coarse grid that measures the volume is refined at most this many times (see choose_radius).
COARSE_REFINEMENTS = 3
#: the grid I reaches at least this many grid spacings beyond the data's box.
MIN_MARGIN = 2.0


@dataclass(frozen=True, eq=False)
class MeshingResult:
    """What a run of the spine produced.

    Attributes
    ----------
    mesh : the valid mesh in user coordinates, with the quality arrays as cell data
    implicit : f on the grid I, in the source's local frame (``frame`` maps it to user coordinates)
    nodes : (n, k) float64, every node the biting placed, user coordinates (the mesh keeps those its cells use)
    radius : R used (user units)
    seconds : step name -> wall-clock seconds
    frame : the source's local frame -> user coordinates
    function : the f that was meshed (local frame): e.g. a LabelledImplicit, whose surfaces name the boundary
    labels : the labels meshed, for a label map (empty: every nonzero label, or not a label map)
    fidelity : how closely the boundary follows the source's samples (user units), or None without samples
    notes : what was done to the data on the way (points dropped, ...), one sentence each
    """

    mesh: Mesh
    implicit: SampledGrid
    nodes: np.ndarray
    radius: float
    seconds: dict = field(default_factory=dict)
    frame: Optional[Frame] = None
    function: Optional[Callable] = None
    labels: tuple = ()
    fidelity: Optional[Fidelity] = None
    notes: tuple = ()

    @property
    def to_physical(self) -> np.ndarray:
        """(k + 1, k + 1) homogeneous map from the frame of ``implicit`` to the frame of ``mesh``."""
        return (self.frame or Frame.identity(self.mesh.dim)).matrix


def a_side(nodes: int, dim: int) -> float:
    """Nodes a side for a grid of ``nodes`` a side in 2-D and 3-D: beyond, as many nodes in all as in 3-D."""
    return nodes ** (3 / max(dim, 3))


def radius_for_cells(measure: float, cells: int, dim: int) -> float:
    """R that gives about ``cells`` cells in a domain of area (2D) or volume (3D) ``measure``."""
    return float((CELLS_PER_VOLUME[dim] * measure / cells) ** (1.0 / dim))


@contextmanager
def timed(seconds: dict, name: str):
    """Add the wall-clock seconds of the ``with`` block to ``seconds[name]``."""
    clock = time.perf_counter()
    yield
    seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - clock


def mesh_from_grid(grid: SampledGrid, biting: BitingParameters, spurious: SpuriousParameters = SpuriousParameters(),
                   progress: ProgressCallback = None, seconds: dict | None = None,
                   optimize: OptimizeParameters = OptimizeParameters(),
                   tagging: Callable[[Mesh], Mesh] = component_tags, interfaces=None,
                   surface_of=None) -> MeshingResult:
    """Mesh {f > 0} of a sampled implicit function; R is ``biting.radius`` or chosen for ``biting.cells`` cells.

    Any dimension k = 2..5 (a k-D grid: :class:`~bitemesh.core.grid.sampled.FunctionGrid`).  With
    ``optimize.optimize`` 1 (the default), the MeshOptimizer step (relaxation, sliver removal) runs on the valid
    domain in 2-D and 3-D, and beyond 3-D the relaxation by new triangulations
    (:func:`~bitemesh.core.steps.retriangulate.relax_by_triangulation`); 0 gives the paper's plain method.
    ``tagging`` tags the valid mesh before its quality is measured (it may move interface nodes,
    :mod:`bitemesh.core.mesh.interfaces`); by default one tag per boundary component.
    ``interfaces`` (a :class:`~bitemesh.core.mesh.interfaces.LabelRegions`, or None): regions whose interfaces the
    biting samples like the boundary.  ``surface_of`` (or None): which of the data's surfaces gives f where; a cut
    that removes a handle touches one of them at most (:func:`~bitemesh.core.steps.handles.break_handles`).
    """
    seconds = {} if seconds is None else seconds
    radius = biting.radius or radius_on_grid(grid, biting.aimed_cells)
    optimize = switched_optimizer(optimize)
    carved = 0.9 if optimize is None else 0.6
    with timed(seconds, "biting"):
        nodes = bite(grid, radius, order=biting.order, seed=biting.seed, progress=sub_progress(progress, 0, 0.3),
                     interfaces=interfaces)
    with timed(seconds, "delaunay"):
        cells = delaunay(nodes)
    report(progress, 0.45, "delaunay")
    with timed(seconds, "spurious cells"):
        mesh = carve_domain(grid, nodes, cells, spurious, progress=sub_progress(progress, 0.45, carved),
                            surface_of=surface_of)
    del cells   # all of Delaunay's cells (32 bytes each): not held through the optimizer
    if optimize is not None:
        with timed(seconds, "optimize"):
            mesh = (optimize_mesh(grid, mesh, optimize, progress=sub_progress(progress, carved, 0.97))
                    if grid.dim <= 3 else
                    relax_by_triangulation(grid, mesh, optimize, spurious, sub_progress(progress, carved, 0.97)))
    with timed(seconds, "tags"):
        mesh = tagging(mesh)
    with timed(seconds, "quality"):
        mesh = mesh.with_cell_data(**cell_quality(mesh))
    report(progress, 1.0, "quality")
    return MeshingResult(mesh=mesh, implicit=grid, nodes=nodes, radius=radius, seconds=seconds)


def switched_optimizer(optimize: OptimizeParameters) -> OptimizeParameters | None:
    """The MeshOptimizer's parameters when its switch is on, else None; bounds given with the switch off are
    pointed out, since they do nothing."""
    if not isinstance(optimize, OptimizeParameters):
        raise InvalidInputError(f"optimize must be OptimizeParameters, got {optimize!r}; e.g. "
                                "OptimizeParameters(optimize=1)")
    if optimize.optimize:
        return optimize
    if replace(optimize, optimize=1) != OptimizeParameters():
        warnings.warn(BitemeshWarning(f"{optimize} has optimize=0: the MeshOptimizer does not run and its bounds "
                                      "do nothing; give optimize=1 to run it"), stacklevel=3)
    return None


def radius_on_grid(grid: SampledGrid, cells: int) -> float:
    """R for about ``cells`` cells in {f > 0} of a sampled f, from its volume counted on the grid."""
    return radius_for_cells(grid.inside_volume(), cells, grid.dim)


def choose_radius(source: Source, cells: int, implicit: ImplicitParameters) -> float:
    """R (local units) for about ``cells`` cells, from the volume of {f > 0}: counted on the source's own grid, or
    on a coarse grid of :data:`COARSE_GRID_NODES` nodes along the box's longest side, refined (up to
    :data:`COARSE_REFINEMENTS` times, each at most 4 x finer) while it is coarser than the R it gives: a plate or a
    rod thinner than the coarse spacing hardly shows on it, and R would come out far too small."""
    dim = source.frame.dim
    if source.grid is not None:
        return radius_on_grid(source.grid, cells)
    finest = _local(implicit.grid_spacing, source) or 0.0
    affordable = implicit.max_memory_mb * 2**20 / BYTES_PER_NODE   # nodes
    coarse = max(source.size / a_side(COARSE_GRID_NODES, dim), finest,
                 2 * float(np.prod(np.asarray(source.upper) - np.asarray(source.lower)) / affordable) ** (1 / dim))
    for refinement in range(COARSE_REFINEMENTS + 1):
        volume = sample_function(source.function, source.lower, source.upper, coarse, margin=2 * coarse,
                                 max_memory_mb=implicit.max_memory_mb,
                                 exact_within=EXACT_WITHIN * coarse).inside_volume()
        radius = radius_for_cells(volume, cells, dim)
        finer = max(radius, coarse / 4, finest)
        shape = grid_shape_unchecked(source.lower - 2 * finer, source.upper + 2 * finer, finer)
        if coarse <= radius or finer >= coarse or refinement == COARSE_REFINEMENTS \
                or np.prod(np.array(shape, float)) > affordable:
            break
        coarse = finer
    if volume == 0:
        raise InvalidInputError(
            f"f is positive nowhere on a grid of spacing {coarse * source.frame.scale:.3g} over the data: nothing "
            "is inside; check that the normals point outward, or give radius (the shape may be thinner than that)")
    return radius


def grid_layout(source: Source, radius: float, implicit: ImplicitParameters):
    """(spacing, margin) of the grid I for node spacing R, local units: ``grid_spacing`` or R / 4 (at least 1/40
    of the box's longest side); ``margin`` or 3 spacings, and at least :data:`MIN_MARGIN` spacings, so that f < 0
    is seen all around the data."""
    spacing = _local(implicit.grid_spacing, source) or min(radius / GRID_PER_RADIUS,
                                                           source.size / a_side(MIN_GRID_NODES, source.frame.dim))
    margin = _local(implicit.margin, source)
    return spacing, max(3 * spacing if margin is None else margin, MIN_MARGIN * spacing)


def check_spacing(source: Source, implicit: ImplicitParameters) -> None:
    """Refuse a grid_spacing too coarse for the data's box: the grid I could not resolve the shape."""
    size = _extent(source) * source.frame.scale
    if implicit.grid_spacing is not None and implicit.grid_spacing > size / 4:
        raise InvalidInputError(
            f"grid_spacing {implicit.grid_spacing:g} is coarser than a quarter of the data's longest side "
            f"({size:.4g}): the grid I cannot resolve the shape; use grid_spacing <= {size / 4:.4g} (at most R / 2) "
            "or omit it (default R / 4)")


def _extent(source: Source) -> float:
    """The longest side of the box that the grid I covers (local units)."""
    return source.size if source.grid is None else float(np.max(source.grid.upper - source.grid.origin))


def check_grid(source: Source, radius: float, implicit: ImplicitParameters, biting: BitingParameters) -> None:
    """Refuse, before any sampling, node spacing R (local units) and a grid I that do not fit the data or the
    memory, naming the parameter to change in user units."""
    scale = source.frame.scale
    size = _extent(source)
    named = "radius" if biting.radius is not None else f"radius (chosen for cells = {biting.aimed_cells})"
    check_number(radius * scale, named, low=0, low_open=True, high=size * scale,
                 hint="radius is R, the node spacing; it cannot exceed the size of the data's bounding box"
                      + ("" if biting.radius is not None else "; ask for more cells"))
    if implicit.grid_spacing is not None and implicit.grid_spacing > radius * scale / 2:
        raise InvalidInputError(
            f"grid_spacing {implicit.grid_spacing:g} is too coarse for {named} = {radius * scale:.4g}: the grid "
            f"must resolve R, grid_spacing <= R / 2 = {radius * scale / 2:.4g}; omit grid_spacing (default R / 4) "
            "or raise radius")
    check_memory(source, radius, implicit, biting)


def check_memory(source: Source, radius: float | None, implicit: ImplicitParameters, biting: BitingParameters) -> None:
    """Refuse a grid I (for node spacing R, local units; None when ``grid_spacing`` is given, which alone sets
    it) over ``max_memory_mb`` or over the memory the machine has free, with a hint in user units that fits."""
    if source.grid is not None:
        return
    scale = source.frame.scale
    spacing, margin = grid_layout(source, np.inf if radius is None else radius, implicit)
    shape = grid_shape_unchecked(source.lower - margin, source.upper + margin, spacing)
    needed = np.prod(np.array(shape, dtype=np.float64)) * BYTES_PER_NODE / 2**20
    available = available_memory_mb()
    limit = min(implicit.max_memory_mb, available or np.inf)
    if needed > limit:
        factor = 1.1 * float((needed / limit) ** (1 / len(shape)))   # 10 % to spare, so that the hint fits
        which = (f"max_memory_mb = {implicit.max_memory_mb:g}" if limit == implicit.max_memory_mb
                 else f"the {available:.0f} MiB of memory this machine has free")
        hint = (f"grid_spacing >= {implicit.grid_spacing * factor:.4g}" if implicit.grid_spacing is not None
                else f"radius >= {radius * scale * factor:.4g}" if biting.radius is not None and radius is not None
                else f"cells <= {int(biting.aimed_cells / factor ** len(shape))}")
        raise InvalidInputError(
            f"the grid I at spacing {spacing * scale:.4g} needs {' x '.join(map(str, shape))} nodes (about "
            f"{needed:.0f} MiB), more than {which}; use {hint}"
            + (" or raise max_memory_mb" if limit == implicit.max_memory_mb else ""))


def check_inside(grid: SampledGrid, radius: float, scale: float, biting: BitingParameters) -> None:
    """Refuse a grid I with nothing inside, or a shape thinner than R along some axis, in user units: the biting
    could place no meaningful nodes there."""
    inside = grid.inside()
    if not inside.any():
        raise InvalidInputError(
            f"nothing is inside the surface on the grid I (spacing {np.max(grid.spacing) * scale:.3g}): the "
            "normals may point inward or disagree, or the shape is thinner than the grid spacing or the samples' "
            "spacing; give outward normals, or a finer grid_spacing")
    extent = float(np.min(inside_extents(inside) * grid.spacing)) + float(np.max(grid.spacing))
    if radius > extent:
        given = biting.radius is not None
        needed = biting.aimed_cells * (radius / (extent / 2)) ** grid.dim
        named = "radius" if given else f"radius (chosen for cells = {biting.aimed_cells})"
        raise InvalidInputError(
            f"{named} = {radius * scale:.4g} exceeds "
            f"the shape's thinnest extent, {extent * scale:.4g}: the shape is too thin for elements that size; give "
            f"radius <= {extent * scale / 2:.4g}" + ("" if given else f" or cells >= {int(np.ceil(needed))}"))


def sample_grid(source: Source, function, radius: float, implicit: ImplicitParameters,
                progress: ProgressCallback = None) -> SampledGrid:
    """The grid I for node spacing R (local units, see :func:`grid_layout`), exact near f = 0; a source's own grid
    when its spacing is between R / 8 and R / 4 (and grid_spacing is not given), else resampled from it."""
    if source.grid is not None:
        target = _local(implicit.grid_spacing, source) or radius / GRID_PER_RADIUS
        if implicit.grid_spacing is None and target / 2 <= np.max(source.grid.spacing) <= target:
            return source.grid
        report(progress, 0.0, f"resampling the distance on a {target * source.frame.scale:.3g} grid")
        return sample_function(source.grid.evaluate, source.grid.origin, source.grid.upper, target,
                               max_memory_mb=implicit.max_memory_mb, progress=progress)
    spacing, margin = grid_layout(source, radius, implicit)
    return sample_function(function, source.lower, source.upper, spacing, margin=margin,
                           max_memory_mb=implicit.max_memory_mb, exact_within=EXACT_WITHIN * spacing,
                           progress=progress)


def _local(value, source: Source):
    """A length in user units (or None) in the source's local units."""
    return None if value is None else value / source.frame.scale


def grid_for_source(source: Source, implicit: ImplicitParameters = ImplicitParameters(),
                    biting: BitingParameters = BitingParameters(), progress: ProgressCallback = None):
    """The grid I of a source and the R it is laid out for (the first steps of :func:`mesh_source`; the VTK chain's
    PointsToImplicit takes them too, so that the chain and MeshFromPoints mesh the same grid).

    R is ``biting.radius``, else the source's own :attr:`~bitemesh.core.sources.source.Source.radius` when
    ``biting.cells`` is not given, else chosen for ``biting.aimed_cells`` cells (:func:`choose_radius`).

    Returns
    -------
    grid : f on the grid I (local frame); radius : R (local units); function : the f that was sampled;
    notes : the source's notes, and the sentence that says R was the source's own
    """
    notes = source.notes
    if biting.radius is None and source.radius is not None and biting.cells is None:
        biting = replace(biting, radius=source.radius * source.frame.scale)
        notes += (source.radius_note,) if source.radius_note else ()
        logger.info(source.radius_note)
    check_spacing(source, implicit)
    radius = _local(biting.radius, source)
    if radius is None:
        radius = choose_radius(source, biting.aimed_cells, implicit)
    check_grid(source, radius, implicit, biting)
    function = source.function if source.at_radius is None else source.at_radius(radius)
    grid = sample_grid(source, function, radius, implicit, progress)
    check_inside(grid, radius, source.frame.scale, biting)
    return grid, radius, function, notes


def mesh_source(source: Source, implicit: ImplicitParameters = ImplicitParameters(),
                biting: BitingParameters = BitingParameters(), spurious: SpuriousParameters = SpuriousParameters(),
                optimize: OptimizeParameters = OptimizeParameters(), progress: ProgressCallback = None,
                seconds: dict | None = None, fidelity: FidelityParameters = FidelityParameters()) -> MeshingResult:
    """Mesh a source: choose R and sample the grid I (:func:`grid_for_source`), bite, Delaunay, carve the valid domain,
    optimize (when ``optimize.optimize`` is 1), tag (the source's :attr:`~bitemesh.core.sources.source.Source.tagging`,
    by default one tag per boundary component), quality, measure the fidelity to the source's samples (refused beyond
    the bounds of ``fidelity``, see :func:`~bitemesh.core.steps.verdict.check_fidelity`), and map the mesh to user
    coordinates.

    Lengths in the parameters (radius, grid_spacing, margin) are in user units.  ``spurious.handles`` "auto" takes
    the source's meaning.
    """
    seconds = {} if seconds is None else seconds
    if spurious.handles == "auto":
        spurious = replace(spurious, handles=source.handles)
    with timed(seconds, "implicit sampling"):
        grid, radius, function, notes = grid_for_source(source, implicit, biting, sub_progress(progress, 0.0, 0.3))
    fixed = BitingParameters(radius=radius, cells=biting.cells, order=biting.order, seed=biting.seed)
    tagging = component_tags if source.tagging is None else partial(source.tagging, function=function)
    surface_of = None if source.surface_of is None else partial(source.surface_of, function)
    result = mesh_from_grid(grid, fixed, spurious, sub_progress(progress, 0.3, 0.97), seconds, optimize, tagging,
                            source.interfaces, surface_of)
    frame = source.frame
    measured, inside = None, grid.inside()
    if source.samples is not None:
        report(progress, 0.97, "measuring the fidelity")
        with timed(seconds, "fidelity"):
            measured, judged = judge_fidelity(source, result.mesh, grid, inside, radius, fidelity,
                                              spurious.min_component)
        notes += judged
    with timed(seconds, "topology"):
        check_topology(result.mesh, inside, radius * frame.scale, bool(fidelity.allow_unfaithful),
                       around=grid.inside_offsets, one_fit=source.one_fit, grid=grid, frame=frame)
    mesh = frame.mesh_to_user(result.mesh)
    voids = enclosed_voids(mesh)
    if voids:
        notes += (f"the mesh encloses {len(voids)} void(s), the largest {voids[0][0]:.3g} in volume around "
                  f"{point_text(voids[0][1])}: cavities that f has too (a hollow object's, or a bubble of the fitted "
                  "surface inside a wall); handles='remove' fills every void",)
    report(progress, 1.0, "done")
    return MeshingResult(mesh=mesh, implicit=grid, nodes=frame.to_user(result.nodes),
                         radius=radius * frame.scale, seconds=seconds, frame=frame, function=function,
                         labels=source.labels, fidelity=measured, notes=notes)
