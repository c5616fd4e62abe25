"""Labelled contours on the meshing spine: :func:`labelled_source` (the domain's f as a
:class:`~bitemesh.core.sources.source.Source`, with what cardiac contours imply: R, the thinnest wall, the handles),
:func:`run_labelled` (the source, the spine, and for a heart the plausibility check).
"""
from __future__ import annotations

import logging
from dataclasses import fields, replace

import numpy as np

from ...errors import check_points
from ...mesh.simplicial import Mesh
from ...mesh.topology import boundary_facets
from ...steps.fidelity import distances_to_facets
from ...parameters import (BitingParameters, FidelityParameters, ImplicitParameters,
                           LabelledParameters, OptimizeParameters, SpuriousParameters, is_optional)
from ...progress import ProgressCallback, sub_progress
from ..source import Frame, Source
from ...steps.spine import MeshingResult, mesh_source, timed
from ...mesh.tags import DOMAIN, MYOCARDIUM, renamed_tags, surface_tags
from .cardiac import (BIVME_SURFACES, CARDIAC_RADIUS, DERIVED_EPI_TAGS, LV_DOMAIN, LV_REGION,
                      LV_TAGS, MIN_WALL, canonical_labels, check_heart, check_millimetres, heart_scale,
                      is_bivme)
from .fit import labelled_implicit
from .function import LabelledImplicit
from .valves import INFLOW_RINGS, rings_off_the_mesh

logger = logging.getLogger("bitemesh")


#: the thinnest wall is at least this x R (so that a wall is about one cell thick), and at least MIN_WALL, when
#: min_wall is not given.
WALL_PER_RADIUS = 1.25


def thinnest_wall(radius: float) -> float:
    """The default min_wall for node spacing R: the larger of :data:`MIN_WALL` and :data:`WALL_PER_RADIUS` x R."""
    return max(MIN_WALL, WALL_PER_RADIUS * radius)


def two_cells_across(radius: float) -> float:
    """The radius that puts about two cells across a heart's thinnest wall: contours keep every wall at least
    max(MIN_WALL, WALL_PER_RADIUS R) thick, one cell and a quarter while R is above MIN_WALL / WALL_PER_RADIUS
    (2 mm), so below that (measured on biv-me patient1's 3-4 mm RV free wall: 46 % of its cells span it at R = 1.83
    mm, 60 % at 2.1, 64 % at 3.7); where R is below it already, half of R."""
    below = 0.9 * MIN_WALL / WALL_PER_RADIUS
    return below if radius > below else radius / 2


#: the result of :func:`run_labelled`; its ``function`` is the LabelledImplicit (for :func:`boundary_surfaces`).
LabelledMeshingResult = MeshingResult


def labelled_tags(mesh: Mesh, function: LabelledImplicit) -> Mesh:
    """``mesh`` of ``function``'s domain (its frame) with every boundary triangle tagged by the surface it lies on
    (:func:`~bitemesh.core.mesh.tags.surface_tags`: tag = position in ``function.names`` + 1; biv-me EPI 1, LV_ENDO 2,
    RV_ENDO 3, BASE 4), one region (MYOCARDIUM for a heart's myocardium, else DOMAIN); an LV-only myocardium as
    cardiac-geometries tags its LV: EPI 7, ENDO 6, BASE 5, MYOCARDIUM 8 (:data:`~.cardiac.LV_TAGS`); a myocardium
    whose RV epicardium was derived has the biventricular tags, LV_EPI and RV_EPI one EPI.

    The valve openings are no triangles of a myocardium: its cavities open through the base plane, so each valve
    is a hole in the BASE ring, bounded where the LV_ENDO or RV_ENDO triangles meet the base.  The base plane is
    one plane through the valves' centres, not the valve rings, so a cavity's domain (a blood pool) has one BASE
    cap for all its valves; splitting that cap by valve is not done.
    """
    tagged = surface_tags(mesh, function.active_surface, function.names,
                          MYOCARDIUM if function.is_myocardium else DOMAIN)
    if function.is_myocardium and function.expression == LV_DOMAIN:
        return renamed_tags(tagged, LV_TAGS, LV_REGION)
    if function.is_myocardium and "RV_EPI" in function.derived:
        return renamed_tags(tagged, DERIVED_EPI_TAGS, 1)
    return tagged


def labelled_keywords(parameters: LabelledParameters, given_only: bool = False) -> dict:
    """LabelledParameters as keywords of :func:`run_labelled` (the CLI, the VTK filters and Slicer all pass them so):
    an empty domain is None (the default domain), base_plane "none" None (no cut), allow_implausible a bool, a
    number left automatic (None) absent (the functions' own default: for a length, an adult heart's, scaled with a
    smaller heart). ``given_only``: only the fields not at their defaults (so that a config file's values stand where
    no flag was given)."""
    keywords = {item.name: getattr(parameters, item.name) for item in fields(LabelledParameters)
                if not (is_optional(item) and getattr(parameters, item.name) is None)}
    if given_only:
        keywords = {name: value for name, value in keywords.items() if value != getattr(LabelledParameters, name)}
    if "domain" in keywords:
        keywords["domain"] = (keywords["domain"] or "").strip() or None   # a GUI's empty text may come as None
    if keywords.get("base_plane") == "none":
        keywords["base_plane"] = None
    if "allow_implausible" in keywords:
        keywords["allow_implausible"] = bool(keywords["allow_implausible"])
    return keywords


def labelled_source(points, labels, *, domain=None, base_plane="auto", slices=None, surfaces=None, min_wall=None,
                    progress: ProgressCallback = None, **options) -> Source:
    """Labelled contour points as a :class:`~bitemesh.core.sources.source.Source`: :func:`labelled_implicit` fitted
    centred on the points' bounding box (in mm still), the thinnest wall following R unless ``min_wall`` is given
    (:func:`thinnest_wall`), R = 2 mm by default for biv-me surfaces
    (:data:`~bitemesh.core.sources.contours.cardiac.CARDIAC_RADIUS`), handles removed from a myocardium, and the
    surface points below the base plane as the samples (the base plane's cap and derived surfaces left out of the
    fidelity), the boundary tagged by surface (:func:`labelled_tags`)."""
    points = check_points(points, dims=(3,))
    frame = _local_frame(points, labels)
    scale = frame.scale
    if base_plane is not None and not isinstance(base_plane, str):
        try:
            point, normal = base_plane
            base_plane = ((np.asarray(point, dtype=np.float64) - frame.shift) / scale, normal)
        except (TypeError, ValueError):
            pass   # labelled_implicit refuses it with its message
    for name in LENGTH_OPTIONS:   # a length given is in the input's unit; the defaults are an adult heart's mm
        if options.get(name) is not None:
            options[name] = options[name] / scale
    function, lower, upper = labelled_implicit(
        (points - frame.shift) / scale, labels, domain, base_plane, slices=slices, surfaces=surfaces,
        min_wall=MIN_WALL if min_wall is None else min_wall / scale, reported_scale=scale, progress=progress,
        **options)
    for note in function.notes:
        logger.info(note)
    cardiac = set(function.surfaces) <= set(BIVME_SURFACES) | set(function.derived)
    ball = function.is_myocardium and function.base is not None   # no handle, no void
    size = f" (a heart {scale:.2g} the size of an adult's, meshed as one: R and every wall with it)" if scale < 1 \
        else ""
    return Source(function, lower, upper, frame, samples=function.surface_samples(),
                  at_radius=(lambda radius: function.with_min_wall(thinnest_wall(radius))) if min_wall is None
                  else None,
                  noise=function.tracing_noise(), gap=function.contour_gap(),
                  open_boundary=function.is_unsampled if function.base is not None or function.derived else None,
                  notes=function.notes, radius=CARDIAC_RADIUS if cardiac else None,
                  radius_note=f"cardiac contours: R = {CARDIAC_RADIUS * scale:.3g} mm{size} (give radius or cells "
                  "for another size)" if cardiac else "", handles="remove" if ball else "keep",
                  tagging=labelled_tags, locate=function.locate, surface_of=LabelledImplicit.data_surface)


#: the options of :func:`labelled_implicit` that are lengths (input units).
LENGTH_OPTIONS = ("offset", "base_offset", "resolution", "rv_wall")


def _local_frame(points, labels) -> Frame:
    """The frame contours are fitted and meshed in: centred on their bounding box, in the input's unit (mm: the
    defaults are an adult heart's mm); contours smaller than an adult heart's, scaled to its size
    (:func:`~bitemesh.core.sources.contours.cardiac.heart_scale`), so that every default length (R, the thinnest
    wall, the fit's offset, the valves' clearances, the base's reach) is the same share of them as of an adult's
    heart: a child's or a mouse's heart, or any other labelled contours in a unit of their own (a unit sphere's
    points were thinned 1.6 apart, one point left)."""
    frame = Frame.around(points, scaled=False)
    try:
        cardiac = is_bivme(canonical_labels(np.asarray(labels).astype(str))[0])
    except (TypeError, ValueError):   # labels that are no labels: labelled_implicit refuses them by name
        cardiac = False
    if cardiac:
        check_millimetres(points)   # here, where a heart in metres is still 1000 times too small
    return Frame(frame.linear * heart_scale(points), frame.shift)


def run_labelled(points, labels, *, domain=None, base_plane="auto", slices=None, surfaces=None, min_wall=None,
                 implicit: ImplicitParameters | None = None, biting: BitingParameters | None = None,
                 spurious: SpuriousParameters | None = None, optimize: OptimizeParameters = OptimizeParameters(),
                 fidelity: FidelityParameters | None = None, allow_implausible: bool = False,
                 progress: ProgressCallback = None, **options) -> LabelledMeshingResult:
    """Every step on labelled contour points: :func:`labelled_source`, then the spine
    (:func:`~bitemesh.core.steps.spine.mesh_source`), then, for a two-cavity or LV myocardium, the plausibility check
    (:func:`~bitemesh.core.sources.contours.cardiac.check_heart`; ``allow_implausible`` turns a refusal into a warning).

    R is ``biting.radius`` or chosen for ``biting.cells`` cells from the volume of the domain; for biv-me surfaces
    with neither given (cells at its default), R = 2 mm.  Parameters left None take their defaults; ``min_wall``
    defaults to :func:`thinnest_wall` of R, so that no wall is thinner than about one cell (a thinner wall would
    open in holes).  ``implicit`` gives the grid I (grid_spacing, margin, max_memory_mb; its method is not used).
    ``optimize`` runs the MeshOptimizer on the valid domain when its switch is 1.  ``options`` go to
    :func:`labelled_implicit` (kernel, offset, outlets, base_offset, resolution, ...).

    ``result.function`` is the domain's LabelledImplicit in the input's coordinates, like the mesh.  The fidelity
    check compares the mesh with the surface points below the base plane, the base plane's cap left out
    (``fidelity``: its bounds, default FidelityParameters()).
    """
    seconds = {}
    with timed(seconds, "implicit fit"):
        source = labelled_source(points, labels, domain=domain, base_plane=base_plane, slices=slices,
                                 surfaces=surfaces, min_wall=min_wall, progress=sub_progress(progress, 0.0, 0.3),
                                 **options)
    result = mesh_source(source, implicit or ImplicitParameters(), biting or BitingParameters(),
                         spurious or SpuriousParameters(), optimize, sub_progress(progress, 0.3, 1.0), seconds,
                         fidelity or FidelityParameters())
    scale = source.frame.scale
    result = replace(result, function=result.function.mapped(scale, source.frame.shift))
    wall = thinnest_wall(result.radius / scale) * scale
    if min_wall is None and wall > MIN_WALL * scale and source.function.is_myocardium:
        note = (f"at R = {result.radius:.3g} the thinnest wall kept is {wall:.3g} (about a cell): walls traced "
                f"thinner (an RV free wall, 2 to 5 mm in an adult) are that thick in the mesh, and the myocardium "
                f"larger than the contours' own; for walls as traced give radius <= "
                f"{MIN_WALL * scale / WALL_PER_RADIUS:.3g} (or min_wall down to {MIN_WALL * scale:.3g})")
        logger.info(note)
        result = replace(result, notes=result.notes + (note,))
    if source.function.is_myocardium:
        with timed(seconds, "plausibility"):
            check_heart(result.mesh, result.function, result.radius, result.fidelity, scale=scale,
                        allow_implausible=allow_implausible)
            notes = _rings_off_the_mesh(result, points, labels, slices)
        for note in notes:
            logger.info(note)
        result = replace(result, notes=result.notes + notes)
    return result


def _rings_off_the_mesh(result, points, labels, slices) -> tuple:
    """:func:`~bitemesh.core.sources.contours.valves.rings_off_the_mesh` on the input's ring points, moved with their
    slices as the registration moved them, beyond R + the tracing noise."""
    labels = np.asarray(labels).astype(str)
    rings = np.flatnonzero(np.isin(labels, INFLOW_RINGS))
    if not len(rings):
        return ()
    slices = np.full(len(labels), -1) if slices is None else np.asarray(slices)
    points = np.array(points, dtype=np.float64)
    for number, shift in result.function.shifts.items():
        points[slices == number] += shift
    distances = np.full(len(points), 0.0)
    distances[rings] = distances_to_facets(points[rings], result.mesh.points[boundary_facets(result.mesh.cells)])
    return rings_off_the_mesh(distances, points, labels, slices, result.radius + result.function.tracing_noise())
