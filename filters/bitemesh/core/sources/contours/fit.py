"""Labelled contour points -> one implicit function per surface -> a domain by CSG, closed at the base:
:func:`labelled_implicit`, the fit of a :class:`~bitemesh.core.sources.contours.function.LabelledImplicit`.

The input is sparse contours (short- and long-axis slices of a cardiac MR study, 8 to 18 mm apart), each point with
a label naming the contour it was drawn on (biv-me's ``SAX_LV_ENDOCARDIAL``, ...).  The steps:

1. Labels -> surfaces (:data:`BIVME_SURFACES` for biv-me labels; otherwise each label is a surface).
2. Slices: the points' slice ids (a GPFile's ``frameID``) or, without them, the planes found by
   :func:`~bitemesh.core.sources.contours.slices.infer_slices`.
3. In-plane normals (:func:`~bitemesh.core.sources.contours.slices.contour_normals`): per surface and slice, the points
   are ordered into polylines (the longest path of their minimum spanning tree, cut at gaps), the polylines chained into
   one loop (a U-shaped long-axis contour is closed across its open end), and each point's normal is perpendicular
   to the polyline in the slice, pointing out of the loop's region.
4. One implicit per surface (:func:`fit_contour_rbf`): a polyharmonic RBF (Carr et al., SIGGRAPH 2001) that is 0
   on the points and +/- delta at off-surface points p -/+ delta n.  The biharmonic kernel phi(r) = r with
   delta = 4 mm was chosen by the measurements of ``benchmarks/bivme.py`` (against the triharmonic r^3, the thin
   plate r^2 log r and MPU): it passes through the points and bends least between slices, with the fewest
   spurious bubbles where short- and long-axis contours disagree.  A cavity also gets a point inside it at the
   centre of each of its valves (:data:`BIVME_OUTLETS`), so that it opens through the base instead of closing in
   a dome just above the last short-axis slice, and its wall runs on :data:`RING_RISE` above each inflow ring point,
   through the base; the epicardium holds each inflow ring point :data:`RING_WALL` inside (fitted again with those
   it left nearer).  The points are thinned to 1.6 mm apart and, beyond 1,200
   constraints, the RBF is a partition of unity of RBFs on overlapping patches (:mod:`bitemesh.core.implicit.rbf`),
   so that denser contours cost about linearly.  Each RBF is sampled once on a fine grid, exactly near its zero
   level (:func:`bitemesh.core.grid.sampled.sample_function` with levels), so the domain is cheap to evaluate on the
   grid I.
5. The domain: a CSG expression (:mod:`bitemesh.core.sources.contours.csg`) of the surfaces, ``-`` difference, ``+``
   union, ``&`` intersection, by min/max of the implicit values (a difference keeps a thinnest wall where two
   surfaces interpolated independently would cross), closed by the base
   (:mod:`bitemesh.core.sources.contours.base`: for a heart, the surface through the valve annuli).

The septum: biv-me's ``*_RV_SEPTUM`` points lie on the right-ventricular face of the interventricular septum.  They
bound the RV cavity (with the free wall, in ``RV_ENDO``) and, seen from the LV, they are the outer face of the LV
wall (in ``LV_EPI`` with the LV epicardial points, for LV-only domains such as ``LV_EPI - LV_ENDO``).  The
biventricular epicardium ``EPI`` does not use them: the septum is inside it.  (biv-me's LV epicardial contours
stop at the RV insertion points; a full LV epicardial ring would put points of ``EPI`` inside the heart.)

Convention as in :mod:`bitemesh.core.grid.sampled`: f > 0 inside, about the signed distance (input units) near f = 0.
"""
from __future__ import annotations

import logging
import re
from dataclasses import replace
from functools import partial

import numpy as np
from scipy.spatial import cKDTree

from ...errors import InvalidInputError, check_choice, check_number, check_points
from ...grid.sampled import ImplicitGrid, sample_function
from ...parameters import LabelledParameters
from ...progress import ProgressCallback, report, sub_progress
from ...implicit.samples import slice_spacing
from .base import ABOVE_VALVES, choose_base
from .cardiac import (BIVME_OUTLETS, BIVME_SURFACES, MIN_WALL, OUTLET_WALL, RV_WALL, bivme_domain, canonical_labels,
                      check_millimetres, default_surfaces, grown, is_bivme, needs_derived_epicardium,
                      short_axis_stack, unused_labels_note)
from .contradicted import without_contradicted
from .csg import domain_names, parse_domain
from .function import LabelledImplicit
from .registration import registered
from .valves import CAVITY_RINGS, INFLOW_RINGS, across_valves, outlet_points, ring_normals, walls_behind
from .slices import GAP_FACTOR, contour_normals, infer_slices, slice_planes
from .surface_fit import OFFSET, PATCH_PER_GAP, fit_contour_rbf

logger = logging.getLogger("bitemesh")

#: an epicardium holds every inflow ring point at least this far inside (mm; the thinnest wall the mesher keeps by
#: default): the epicardial contours end short of the annulus, and a wall tapering to nothing there would leave the
#: ring points mm away from the mesh (up to 4.6 mm on the cine's frame 7).
RING_WALL = MIN_WALL
#: a cavity's wall runs on this far (mm) above each inflow ring point, through the base that passes ABOVE_VALVES
#: above it: fitted through the ring alone, the cavity closed in a dome just above it, under a roof of wall thinner
#: than a cell that the mesh lost, mitral points up to 8 mm from the mesh.
RING_RISE = 2 * ABOVE_VALVES


# --- labels and slices -------------------------------------------------------------------------------------------

def _as_labels(labels, count: int) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.ndim != 1 or len(labels) != count:
        raise InvalidInputError(f"labels must hold one label per point ({count}), got shape {labels.shape}")
    if labels.dtype.kind == "f":
        if not np.all(np.isfinite(labels)) or np.any(labels != np.round(labels)):
            raise InvalidInputError("labels must be whole numbers or strings; got non-integer floats")
        labels = labels.astype(np.int64)
    return np.array([str(label).strip() for label in labels.tolist()], dtype=object).astype(str)


# --- fast evaluation on many points ---------------------------------------------------------------------------------

#: each surface is sampled on a grid of at most this many nodes (256 MiB): its spacing grows if needed.
MAX_SURFACE_NODES = 1 << 25
#: and exactly only within this x its spacing of its zero level, on grids 2 and 4 times coarser first.
SURFACE_BAND, SURFACE_LEVELS = 2.0, 3


def _nodes(lower, spacing, shape) -> np.ndarray:
    """(prod(shape), 3) coordinates of the grid nodes, C order (axis 0 is x)."""
    axes = [lower[d] + np.arange(shape[d]) * spacing for d in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


# --- everything together ---------------------------------------------------------------------------------------------

def _checked_surfaces(surfaces, labels) -> dict:
    if surfaces is None:
        return default_surfaces(labels)
    if not isinstance(surfaces, dict) or not surfaces:
        raise InvalidInputError(f"surfaces must map surface names to labels, got {surfaces!r}")
    checked = {}
    for name, members in surfaces.items():
        if not re.fullmatch(r"[A-Za-z0-9_.:]+", str(name)):
            raise InvalidInputError(f"surface name {name!r} must be letters, digits, '_', '.' or ':'")
        members = (members,) if isinstance(members, (str, int, np.integer)) else tuple(members)
        checked[str(name)] = tuple(str(member) for member in members)
    return checked


def _default_domain(surfaces: dict, labels, points) -> tuple:
    """The domain expression for these labels, and a note."""
    if is_bivme(labels):
        return bivme_domain(labels)
    present = [name for name, members in surfaces.items() if np.isin(labels, members).any()]
    if len(present) == 1:
        return present[0], ()
    span = {name: float(np.linalg.norm(np.ptp(points[np.isin(labels, surfaces[name])], axis=0))) for name in present}
    present.sort(key=lambda name: -span[name])   # the widest first: what holds the others
    raise InvalidInputError(
        f"the points have {len(present)} surfaces ({', '.join(present)}): give domain, a CSG expression of them "
        f"such as {' - '.join(present[:3])!r} (the widest first: the cavities it holds subtracted from it)")


def _distinct(points, index) -> np.ndarray:
    """``index`` without the points that repeat an earlier one (biv-me repeats some contours; contours on slices
    that cross share the points on the crossing line), within 1e-6 x the bounding-box diagonal."""
    tolerance = 1e-6 * float(np.linalg.norm(np.ptp(points[index], axis=0))) if len(index) else 0.0
    pairs = cKDTree(points[index]).query_pairs(tolerance, output_type="ndarray")
    keep = np.ones(len(index), bool)
    keep[pairs.max(axis=1)] = False
    return index[keep]


def labelled_implicit(points, labels, domain=None, base_plane="auto", *, slices=None, surfaces=None, outlets=None,
                      slice_shifts: str = LabelledParameters.slice_shifts,
                      kernel: str = LabelledParameters.kernel, offset: float = OFFSET,
                      smoothing: float = LabelledParameters.smoothing,
                      base_offset: float = LabelledParameters.base_offset, min_wall: float = MIN_WALL,
                      rv_wall: float = RV_WALL, gap_factor: float = GAP_FACTOR, resolution=None,
                      reported_scale: float = 1.0, progress: ProgressCallback = None):
    """The implicit function of a domain bounded by several labelled contour surfaces.

    Parameters
    ----------
    points : (n, 3) float64, contour points, input units (mm)
    labels : (n,) str or int, the contour label of each point (biv-me's, CVI42's or without the SAX/LAX prefix:
        :func:`bitemesh.core.sources.contours.cardiac.canonical_labels`)
    domain : str, CSG expression of surface names (``-``, ``+``, ``&``, parentheses); default: for biv-me labels
        :data:`BIVME_DEFAULT_DOMAIN` (``LV_EPI - LV_ENDO`` without RV contours; without RV epicardial contours EPI
        is ``LV_EPI + RV_EPI``, RV_EPI derived: :mod:`bitemesh.core.sources.contours.cardiac`), else the only surface
    base_plane : "auto" (for biv-me labels the surface through the valve annuli and the long-axis contours' upper ends,
        :func:`bitemesh.core.sources.contours.base.annulus_surface`, without them the basal short-axis slice; for other
        labels the least-squares plane of at least 3 valve points, else none), "valves" (required: the same with valve
        points, without a short-axis stack their least-squares plane, the apex inside), None (no cut), or (point,
        normal) a plane, the normal pointing out of the domain
    slices : (n,) int slice id per point (a GPFile's frameID), or None to find them
        (:func:`~bitemesh.core.sources.contours.slices.infer_slices`)
    slice_shifts : "auto" (for cardiac labels, every slice moved in its plane so that the contours of each surface meet
        where the slices cross: :mod:`bitemesh.core.sources.contours.registration`, and the points of a short-axis
        contour the other slices contradict left out: :mod:`~bitemesh.core.sources.contours.contradicted`; other
        labels as given) or "none"
    surfaces : dict name -> labels, default :func:`default_surfaces`
    outlets : dict surface name -> valve labels through which that cavity opens (see :data:`BIVME_OUTLETS`, the
        default for biv-me labels; {} for none)
    kernel, offset, smoothing : of :func:`fit_contour_rbf`
    base_offset : float, input units, moves the base along its normal (> 0: away from the apex)
    min_wall : float, input units, the thinnest wall between a surface and what is subtracted from it (see
        :func:`~bitemesh.core.sources.contours.csg.evaluate_domain`); 0 lets walls open where the surfaces cross
    rv_wall : float, mm, the RV free wall thickness a missing RV epicardium is derived with
    gap_factor : float, of :func:`~bitemesh.core.sources.contours.slices.contour_normals`
    resolution : float, input units, the spacing of the grid each surface is sampled on (an ImplicitGrid);
        default 0.35 x the median spacing of the surface's points (1 mm for contours traced on 1.4 mm pixels), at
        least offset / 4 (denser contours say no more between the slices) and 1/400 of its bounding-box diagonal
    reported_scale : float, the input's units per unit of ``points`` in the lengths the notes give (a small heart's
        contours are fitted scaled to an adult's size: :func:`~bitemesh.core.sources.contours.run.labelled_source`)
    progress : callable(fraction, message), optional

    Returns
    -------
    f : LabelledImplicit, callable (m, 3) -> (m,), f > 0 inside
    lower, upper : (3,) float64, a box holding the domain (the Source's box)
    """
    points = check_points(points, dims=(3,))
    labels, notes = canonical_labels(_as_labels(labels, len(points)))
    if is_bivme(labels):
        check_millimetres(points)
        notes += unused_labels_note(labels)
    surfaces = _checked_surfaces(surfaces, labels)
    if domain is None:
        expression, note = _default_domain(surfaces, labels, points)
        notes += note
    else:
        expression = domain
    tree = parse_domain(expression, surfaces)
    grown_from = {}   # surface name -> the fitted surface whose distance it is
    if domain is None and is_bivme(labels) and surfaces == BIVME_SURFACES:
        tree, grown_from, note = _derived_epicardium(tree, labels, check_number(rv_wall, "rv_wall", low=0,
                                                                                 low_open=True), reported_scale)
        notes += note
    derived = tuple(grown_from)
    used = domain_names(tree)
    for name in used:
        if name not in grown_from and not np.isin(labels, surfaces[name]).any():
            present = ", ".join(f"{label} ({count})" for label, count in zip(*np.unique(labels, return_counts=True)))
            raise InvalidInputError(
                f"surface {name} needs points labelled {' or '.join(surfaces[name])}, and the input has none; "
                f"labels present: {present}")
    if slices is None:
        report(progress, 0.0, "finding the slice planes")
        slices = infer_slices(points)
    else:
        slices = np.asarray(slices)
        if slices.shape != (len(points),) or slices.dtype.kind not in "iu":
            raise InvalidInputError(f"slices must hold one integer id per point ({len(points)}), got shape "
                                    f"{slices.shape} of {slices.dtype}")
        slices = np.where(slices >= 0, slices, -1).astype(np.int64)
    fitted = [name for name in used if name not in grown_from]
    if is_bivme(labels):
        across, note = across_valves(points, labels, slices, [label for name in fitted for label in surfaces[name]])
        points, labels, slices, notes = points[~across], labels[~across], slices[~across], notes + note
    shifts, disagreement = {}, 0.0
    # breath-hold shifts are cardiac MR's: other labelled contours (a surface sampled in planes, a volume's
    # segmentation traced slice by slice) are taken as given, not moved to meet
    if check_choice(slice_shifts, "slice_shifts", ("auto", "none")) == "auto" and is_bivme(labels):
        points, labels, slices, registration = registered(points, labels, slices,
                                                          {name: surfaces[name] for name in fitted}, gap_factor)
        notes += registration.notes(reported_scale)
        shifts, disagreement = registration.shifts, registration.disagreement
        points, labels, slices, note = without_contradicted(
            points, labels, slices, registration.contradicted, surfaces, gap_factor=gap_factor, scale=reported_scale,
            kernel=kernel, offset=offset, smoothing=smoothing)
        notes += note
    planes = slice_planes(points, slices)
    outlets = (BIVME_OUTLETS if is_bivme(labels) else {}) if outlets is None else dict(outlets)
    in_any = np.isin(labels, [label for name in used if name not in grown_from for label in surfaces[name]])
    base, note = choose_base(base_plane, points, labels, points[in_any], slices, planes)
    notes += note
    basal_slice = ()
    if base is not None:
        base = base.raised(check_number(base_offset, "base_offset"))
        axis, stack, heights = short_axis_stack(points, labels, slices, planes)
        if axis is not None:
            basal_slice = (planes[stack[int(np.argmax(heights))]].centre, axis)

    functions, surface_points, surface_normals, surface_slices = {}, {}, {}, {}
    for number, name in enumerate(fitted):
        report(progress, 0.05 + 0.9 * number / len(fitted), f"fitting surface {name}")
        index = _distinct(points, np.flatnonzero(np.isin(labels, surfaces[name])))
        normals = _surface_normals(points[index], slices[index], planes, name, gap_factor)
        min_patch = PATCH_PER_GAP * slice_spacing(points[index], slices[index])
        if name in CAVITY_RINGS:   # a cavity's inflow annulus lies on its wall, its normal away from the valve's centre
            rings = _distinct(points, np.flatnonzero(np.isin(labels, CAVITY_RINGS[name])))
            index, normals = np.r_[index, rings], np.vstack([normals, ring_normals(
                points[rings], labels[rings], slices[rings], points[index], slices[index], normals)])
        fitted_points, fitted_normals = points[index], normals
        if name in CAVITY_RINGS and base is not None and len(rings):   # the wall runs on up through the base
            risen = points[rings] + RING_RISE * base.outward(points[rings])
            fitted_points = np.vstack([fitted_points, risen])
            fitted_normals = np.vstack([fitted_normals, normals[-len(rings):]])
        interior = outlet_points(points, labels, outlets.get(name, ()), OUTLET_WALL.get(name, 0.0))
        fit_surface = partial(fit_contour_rbf, fitted_points, fitted_normals, kernel=kernel, offset=offset,
                              smoothing=smoothing, min_patch=min_patch)
        rbf = fit_surface(interior=interior)
        ring_points = points[np.isin(labels, [valve for valve in outlets.get(name, ()) if valve in INFLOW_RINGS])]
        thin = ring_points[rbf(ring_points) < RING_WALL] if name in OUTLET_WALL and len(ring_points) else []
        if len(thin):   # the epicardium holds each inflow ring point a wall inside it: fitted again with them
            rbf = fit_surface(interior=_joined(interior, thin, np.full(len(thin), RING_WALL)))
        if name in CAVITY_RINGS and len(rings):   # and a cavity leaves a wall behind each: no pocket there
            behind = walls_behind(rbf, points[rings], normals[-len(rings):], RING_WALL)
            if len(behind[0]):
                rbf = fit_surface(interior=_joined(interior, *behind))
        functions[name] = _sampled_surface(rbf, points[index], offset, resolution, sub_progress(
            progress, 0.05 + 0.9 * (number + 0.3) / len(fitted), 0.05 + 0.9 * (number + 1) / len(fitted)))
        surface_points[name], surface_normals[name], surface_slices[name] = points[index], normals, slices[index]
    distances = {name: grown(functions[name], 0.0) for name in set(grown_from.values())}
    functions.update({name: distances[source] for name, source in grown_from.items()})
    function = LabelledImplicit(surfaces={name: functions[name] for name in used}, tree=tree, expression=expression,
                                base=base, min_wall=check_number(min_wall, "min_wall", low=0),
                                lower=points[in_any].min(axis=0), upper=points[in_any].max(axis=0),
                                points=surface_points, normals=surface_normals, slices=surface_slices,
                                derived=derived, shifts=shifts, disagreement=disagreement, basal_slice=basal_slice,
                                notes=notes)
    lower, upper = _domain_box(function)
    report(progress, 1.0, "surfaces fitted")
    function = replace(function, lower=lower, upper=upper)
    return function, lower, upper


def _joined(interior, centres, values) -> tuple:
    """The interior values ``interior`` ((k, 3), (k,), or None) with more ``centres`` (j, 3) and ``values`` (j,)."""
    known, given = interior if interior is not None else (np.zeros((0, 3)), np.zeros(0))
    return np.vstack([known, centres]), np.r_[given, values]


def _derived_epicardium(tree, labels, rv_wall: float, reported_scale: float = 1.0):
    """Without RV epicardial contours: the domain with EPI replaced by ``LV_EPI`` joined to the RV cavity grown by
    ``rv_wall`` (``RV_EPI``, a surface grown from RV_ENDO), and a note (its length times ``reported_scale``); else
    the domain unchanged."""
    if not needs_derived_epicardium(labels, domain_names(tree)):
        return tree, {}, ()

    def substituted(node):
        if node[0] == "name":
            return ("+", ("name", "LV_EPI"), ("grow", "RV_EPI", rv_wall)) if node[1] == "EPI" else node
        return (node[0], substituted(node[1]), substituted(node[2]))

    return substituted(tree), {"RV_EPI": "RV_ENDO"}, (
        f"no RV epicardial contours: the RV epicardium is derived, the RV endocardium grown by rv_wall = "
        f"{rv_wall * reported_scale:.3g} mm and joined to the LV epicardium at the RV insertions",)


def _surface_normals(points, slices, planes, name: str, gap_factor: float) -> np.ndarray:
    """The in-plane normals of one surface's distinct points, after checking that they can bound a volume."""
    if len(points) < 10:
        raise InvalidInputError(f"surface {name} has {len(points)} distinct points; it needs at least 10")
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if spread[2] <= 1e-6 * spread[0]:
        raise InvalidInputError(
            f"the contours of surface {name} all lie in one plane, so they enclose no volume; it needs "
            "contours on at least two slices")
    return contour_normals(points, slices, planes, gap_factor=gap_factor)


def _sampled_surface(rbf, points, offset: float, resolution, progress) -> ImplicitGrid:
    """One surface's RBF sampled on its grid (see ``resolution`` in :func:`labelled_implicit`)."""
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    if resolution is None:
        spacing = float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))
        step = max(0.35 * spacing, offset / 4, diagonal / 400)
    else:
        step = check_number(resolution, "resolution", low=0, low_open=True)
    margin = 0.15 * np.ptp(points, axis=0) + 4 * step
    lower, upper = points.min(axis=0) - margin, points.max(axis=0) + margin
    step = max(step, float(np.prod(upper - lower) / MAX_SURFACE_NODES) ** (1 / 3))
    return sample_function(rbf, lower, upper, step, exact_within=SURFACE_BAND * step, levels=SURFACE_LEVELS,
                           progress=progress)


def _domain_box(function: LabelledImplicit):
    """The box of the nodes with f > 0 of a grid over the surfaces' grids (4 x their spacing), one step larger.

    Raises InvalidInputError when no node is inside: the surfaces enclose nothing, or the domain is empty.
    """
    grids = list(function.surfaces.values())
    lower = np.min([grid.origin for grid in grids], axis=0)
    upper = np.max([grid.upper for grid in grids], axis=0)
    step = 4 * min(grid.spacing.min() for grid in grids)
    shape = tuple(np.ceil((upper - lower) / step).astype(int) + 1)
    nodes = _nodes(lower, step, shape)
    inside = np.zeros(len(nodes), bool)
    for start in range(0, len(nodes), 1 << 18):
        inside[start:start + (1 << 18)] = function(nodes[start:start + (1 << 18)]) > 0
    if not inside.any():
        raise InvalidInputError(
            f"the domain {function.expression!r} is empty: no point is inside it"
            + (" below the base" if function.base is not None else "")
            + "; check that the contours enclose the regions the expression combines (and the base's side)")
    return nodes[inside].min(axis=0) - step, nodes[inside].max(axis=0) + step
