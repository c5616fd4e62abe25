"""biv-me cardiac contours as they come: their labels (and the CVI42 / CAP names, with or without the SAX/LAX prefix),
which surfaces they sample, what to derive when a surface is missing, and what a cardiac user checks on the mesh.

- **Labels** (:func:`canonical_labels`): ``LV_ENDOCARDIAL`` and ``saendocardialContour`` are read as
  ``SAX_LV_ENDOCARDIAL``; labels that are none of biv-me's are listed in a note and not used.
- **Missing RV epicardium** (:func:`derived_epicardium`): many biv-me and CAP datasets trace the RV free wall's
  endocardium only.  The epicardium is then the LV epicardium (``LV_EPI``, with the septum's RV face) joined to the
  RV cavity grown by the RV wall thickness (:data:`RV_WALL`, 3 mm, the normal adult RV free wall; biv-me uses the
  same): ``EPI = LV_EPI + RV_EPI``.  The union meets the LV epicardium at the RV insertions.
- **LV only**: without RV contours the domain is ``LV_EPI - LV_ENDO``.
- **Base**: the surface through the valve annuli (:mod:`bitemesh.core.sources.contours.base`), its heights measured
  along the short-axis stack (:func:`short_axis_stack`).
- **Size**: R = :data:`CARDIAC_RADIUS` (2 mm) unless a radius or a cell count is given; a heart smaller than an
  adult's is fitted and meshed in a frame scaled to an adult's size (:func:`heart_scale`).
- **Plausibility** (:func:`check_heart`): each cavity open at the base and not filled, the myocardial volume and
  mean wall thickness in physiological ranges, the guide points near their surface; otherwise a refusal naming what
  failed (or a warning with ``allow_implausible``).
"""
from __future__ import annotations

import logging
import warnings

import numpy as np

from ...errors import BitemeshWarning, InvalidInputError, MeshingError, check_number
from ...grid.sampled import ImplicitGrid

#: biv-me guide-point labels -> the surfaces they sample (see bitemesh.core.sources.contours.fit for the septum).
# biv-me splits  the RV endocardium into free wall and septum (older exports: RV_ENDOCARDIAL; the outflow tract:
# OUTLET_* and  SAX_RV_OUTLET), and its LV epicardial contours stop at the RV insertions (the septum's RV face is
# RV_SEPTUM).
BIVME_SURFACES = {
    "EPI": ("SAX_LV_EPICARDIAL", "LAX_LV_EPICARDIAL", "SAX_RV_EPICARDIAL", "LAX_RV_EPICARDIAL",
            "OUTLET_RV_EPICARDIAL", "SAX_EPICARDIAL", "LAX_EPICARDIAL"),
    "LV_ENDO": ("SAX_LV_ENDOCARDIAL", "LAX_LV_ENDOCARDIAL"),
    "RV_ENDO": ("SAX_RV_FREEWALL", "LAX_RV_FREEWALL", "SAX_RV_SEPTUM", "LAX_RV_SEPTUM", "SAX_RV_ENDOCARDIAL",
                "LAX_RV_ENDOCARDIAL", "SAX_RV_OUTLET", "OUTLET_RV_FREEWALL", "OUTLET_RV_SEPTUM"),
    "LV_EPI": ("SAX_LV_EPICARDIAL", "LAX_LV_EPICARDIAL", "SAX_RV_SEPTUM", "LAX_RV_SEPTUM"),
}
#: the labels of the RV epicardium; without them it is derived (:func:`derived_epicardium`).
RV_EPICARDIAL = ("SAX_RV_EPICARDIAL", "LAX_RV_EPICARDIAL", "OUTLET_RV_EPICARDIAL")
#: the valve annulus points a base plane is fitted to.
BIVME_VALVES = ("MITRAL_VALVE", "AORTA_VALVE", "TRICUSPID_VALVE", "PULMONARY_VALVE")
#: the valves through which each cavity opens: each valve's centre is a point inside the cavity, at the valve's
#: radius from its wall, so that the cavity reaches through the base instead of closing in a dome below it; the
#: epicardium holds the valves too, a wall's thickness beyond their rims (:data:`OUTLET_WALL`).
BIVME_OUTLETS = {"LV_ENDO": ("MITRAL_VALVE", "AORTA_VALVE"), "RV_ENDO": ("TRICUSPID_VALVE", "PULMONARY_VALVE"),
                 "EPI": BIVME_VALVES, "LV_EPI": ("MITRAL_VALVE", "AORTA_VALVE")}
#: an epicardium's valve constraint: the valve's radius plus this (mm), about a wall's thickness.
OUTLET_WALL = {"EPI": 5.0, "LV_EPI": 5.0}
#: points that must lie below the base plane (they orient it).
BIVME_APEX = ("APEX_POINT", "APEX_EPI_POINT", "APEX_ENDO_POINT")
#: every label biv-me writes (RV_INSERT marks where the RV wall meets the septum, *_PHANTOM are generated valve
#: points, *_EXTENT mark the long-axis extent; bitemesh does not use them).
BIVME_LABELS = frozenset(
    {label for labels in BIVME_SURFACES.values() for label in labels} | set(BIVME_VALVES) | set(BIVME_APEX)
    | {"RV_INSERT", "LAX_LA", "LAX_RA", "LAX_LV_EXTENT", "LAX_RV_EXTENT", "LAX_LA_EXTENT", "LAX_RA_EXTENT",
       "MITRAL_PHANTOM", "TRICUSPID_PHANTOM", "AORTA_PHANTOM", "PULMONARY_PHANTOM", "EXCLUDED"})
#: CVI42 contour names (as CAP-style exports write them, compared in lower case) -> biv-me labels.
CVI42_NAMES = {
    "saendocardialcontour": "SAX_LV_ENDOCARDIAL", "saendocardialopencontour": "SAX_LV_ENDOCARDIAL",
    "saepicardialcontour": "SAX_LV_EPICARDIAL", "saepicardialopencontour": "SAX_LV_EPICARDIAL",
    "sarvendocardialcontour": "SAX_RV_ENDOCARDIAL", "sarvepicardialcontour": "SAX_RV_EPICARDIAL",
    "laendocardialcontour": "LAX_LV_ENDOCARDIAL", "laepicardialcontour": "LAX_LV_EPICARDIAL",
    "larvendocardialcontour": "LAX_RV_ENDOCARDIAL", "larvepicardialcontour": "LAX_RV_EPICARDIAL",
    "rvfw": "SAX_RV_FREEWALL", "rvs": "SAX_RV_SEPTUM", "bp_point": "MITRAL_VALVE",
    "laxlvextentpoints": "LAX_LV_EXTENT", "laxrvextentpoints": "LAX_RV_EXTENT", "laxlaextentpoints": "LAX_LA_EXTENT",
    "laxraextentpoints": "LAX_RA_EXTENT", "lalacontour": "LAX_LA", "laracontour": "LAX_RA",
}
#: the two-cavity myocardium, the default domain for biv-me labels; and the LV's, without RV contours.
BIVME_DEFAULT_DOMAIN = "EPI - LV_ENDO - RV_ENDO"
LV_DOMAIN = "LV_EPI - LV_ENDO"
#: the tags of an LV-only myocardium (LV_DOMAIN) as cardiac-geometries names and numbers its LV (the names ldrb,
#: fenicsx-pulse and cardiac-geometries read): the domain's surface -> (tag name, tag); and its region's tag.
#: Tags 1-4 are cardiac-geometries' apex points and base rings.
LV_TAGS = {"LV_EPI": ("EPI", 7), "LV_ENDO": ("ENDO", 6), "BASE": ("BASE", 5)}
LV_REGION = 8
#: the tags of a biventricular myocardium whose RV epicardium was derived (LV_EPI + RV_EPI): those of every
#: biventricular mesh, the two epicardial parts one EPI.
DERIVED_EPI_TAGS = {"LV_EPI": ("EPI", 1), "RV_EPI": ("EPI", 1), "LV_ENDO": ("LV_ENDO", 2),
                    "RV_ENDO": ("RV_ENDO", 3), "BASE": ("BASE", 4)}
#: the RV free wall thickness (mm) an RV epicardium is derived with: normal adult RV walls are 2 to 5 mm thick.
RV_WALL = 3.0
#: the thinnest wall the domain keeps by default (min_wall, input units): the RV free wall of adult hearts is 2 to
#: 5 mm thick.
MIN_WALL = 2.5
#: the node spacing R (mm) of a cardiac mesh when neither radius nor cells is given: about 100,000 cells for an
#: adult biventricular myocardium, two to five cells across the LV wall.
CARDIAC_RADIUS = 2.0
#: the myocardial volume (ml) and the mean wall thickness (mm) a heart may have: beyond both ends of human hearts,
#: from a child's LV (10 ml) to hypertrophied adult biventricular myocardia (600 ml); the thickness 2 V / area of
#: the walls, from an RV free wall (2 mm) to beyond hypertrophic LV walls (20 mm).
MYOCARDIAL_VOLUME = (10.0, 800.0)
WALL_THICKNESS = (1.5, 20.0)
#: how long (in R) a cavity's endocardium may meet the epicardium below the rim of its opening (check_heart): a hole
#: about three cells across (its rim pi x 3 R).  On biv-me patient1's cine the most is 4.5 R, on every class of
#: variation 6 R; the cavities opened through their walls before were 25-140 R.
OPENING = 10.0
#: a heart mesh's tags of each cavity's endocardium (biventricular, LV-only) and of the epicardium (derived too):
#: where they meet (:func:`~bitemesh.core.mesh.tags.lips`) a cavity opens beside the base.
ENDOCARDIAL_TAGS = {"LV_ENDO": ("LV_ENDO", "ENDO"), "RV_ENDO": ("RV_ENDO",)}
EPICARDIAL_TAGS = ("EPI", "LV_EPI", "RV_EPI")
#: the least and the largest span (mm, the diagonal of the contours' bounding box) of a heart: a mouse heart is
#: about 8 mm long, a horse's about 250 mm.
SMALLEST_HEART, LARGEST_HEART = 5.0, 1000.0
#: the span (mm) of the smallest adult human heart's contours the defaults in mm are for (biv-me's patients span
#: 149-230 mm, end-systole included); contours that span less are a child's or an animal's heart, fitted and meshed
#: in a frame scaled to this span (:func:`heart_scale`), the plausible volume and wall thickness shrinking with
#: them: at R = 2 mm and walls kept 2.5 mm thick a heart 0.3 the size was refused as implausible (8 ml of walls
#: thickened to a cell), and a mouse's (0.1) kept none of its walls.
ADULT_SPAN = 140.0


def canonical_labels(labels):
    """biv-me labels as biv-me spells them, and a note on what was renamed.

    Upper or lower case, spaces or dashes for '_', no SAX_/LAX_ prefix (read as SAX_) and CVI42 names
    (:data:`CVI42_NAMES`) are understood.  Labels that none of these make a biv-me label stay as they are.

    Parameters
    ----------
    labels : (n,) str

    Returns
    -------
    labels : (n,) str; notes : tuple of str
    """
    labels = np.asarray(labels).astype(str)
    names, inverse = np.unique(labels, return_inverse=True)
    renamed = {}
    for name in names.tolist():
        key = "_".join(name.strip().upper().replace("-", " ").split())
        for candidate in (key, f"SAX_{key}", CVI42_NAMES.get(name.strip().lower())):
            if candidate in BIVME_LABELS:
                if candidate != name:
                    renamed[name] = candidate
                break
    if not renamed:
        return labels, ()
    new = np.array([renamed.get(name, name) for name in names.tolist()])[inverse.reshape(-1)]
    shown = ", ".join(f"{old} -> {new}" for old, new in list(renamed.items())[:6])
    return new, (f"labels read as biv-me's: {shown}" + (", ..." if len(renamed) > 6 else ""),)


def check_millimetres(points) -> None:
    """Refuse cardiac contours (n, 3) too small or too large to be a heart in mm (coordinates in metres or in
    micrometres), naming their span."""
    span = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
    if span < SMALLEST_HEART:
        raise InvalidInputError(
            f"cardiac contours are read in mm, and a heart spans at least {SMALLEST_HEART:g} mm (a mouse heart is "
            f"about 8 mm long); these span {span:.3g} (the diagonal of their bounding box): in metres? give the "
            "coordinates in mm (multiply them by 1000)")
    if span > LARGEST_HEART:
        raise InvalidInputError(
            f"cardiac contours are read in mm, and a heart spans at most {LARGEST_HEART:g} mm (a horse's is about "
            f"250 mm long); these span {span:.3g} (the diagonal of their bounding box): in micrometres? give the "
            "coordinates in mm (divide them by 1000)")


def heart_scale(points) -> float:
    """How large the heart of contour points (n, 3) in mm is against an adult's: their span (the diagonal of their
    bounding box) over :data:`ADULT_SPAN`, at most 1."""
    span = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else ADULT_SPAN
    return min(1.0, span / ADULT_SPAN)


def is_bivme(labels) -> bool:
    """True when any label is one of biv-me's guide-point labels."""
    return bool(set(np.unique(np.asarray(labels).astype(str)).tolist()) & BIVME_LABELS)


def default_surfaces(labels) -> dict:
    """The surfaces of these labels: :data:`BIVME_SURFACES` for biv-me labels, else one surface per label."""
    labels = np.asarray(labels).astype(str)
    if is_bivme(labels):
        return dict(BIVME_SURFACES)
    return {label: (label,) for label in np.unique(labels).tolist()}


def unused_labels_note(labels) -> tuple:
    """A note listing the labels of biv-me data that bitemesh does not know (with their counts), or ()."""
    names, counts = np.unique(np.asarray(labels).astype(str), return_counts=True)
    unknown = [(name, count) for name, count in zip(names.tolist(), counts.tolist()) if name not in BIVME_LABELS]
    if not unknown:
        return ()
    return (f"labels not used ({len(unknown)}, not biv-me's): "
            + ", ".join(f"{name} ({count} points)" for name, count in unknown[:10]) + (", ..." if len(unknown) > 10
                                                                                        else ""),)


def bivme_domain(labels) -> tuple:
    """The default domain of biv-me labels and a note: the two-cavity myocardium, or the LV's without RV
    contours."""
    if np.isin(labels, BIVME_SURFACES["RV_ENDO"]).any():
        return BIVME_DEFAULT_DOMAIN, ()
    return LV_DOMAIN, (f"no RV contours: meshed as the left ventricle ({LV_DOMAIN})",)


def needs_derived_epicardium(labels, used_names) -> bool:
    """True when the domain uses EPI, the RV endocardium is traced and the RV epicardium is not."""
    return ("EPI" in used_names and np.isin(labels, BIVME_SURFACES["RV_ENDO"]).any()
            and not np.isin(labels, RV_EPICARDIAL).any())


def grown(grid, thickness: float):
    """The ImplicitGrid of ``grid``'s region grown by ``thickness`` (input units): f / |grad f| + thickness, f / |grad
    f| being about the signed distance near f = 0 (|grad f| bounded to [0.5, 2])."""
    slope = np.sqrt(sum(component ** 2 for component in np.gradient(grid.values, *grid.spacing)))
    return ImplicitGrid(origin=grid.origin, spacing=grid.spacing,
                        values=grid.values / np.clip(slope, 0.5, 2.0) + float(thickness))


def short_axis_stack(points, labels, slices, planes):
    """The short-axis stack: the largest set of parallel slices (within 10 degrees).

    Returns
    -------
    axis : (3,) unit, the stack's normal pointing to the base: away from the apex point or, without one, toward
        the end where the LV endocardial contours are wider; numbers : the stack's slice ids; heights : their
        planes' heights along ``axis``.  None (three times) for fewer than two parallel slices.
    """
    numbers = [number for number in planes if number >= 0]
    if len(numbers) < 2:
        return None, None, None
    normals = np.array([planes[number].normal for number in numbers])
    parallel = np.abs(normals @ normals.T) > np.cos(np.radians(10))
    stack = np.flatnonzero(parallel[np.argmax(parallel.sum(axis=1))])
    if len(stack) < 2:
        return None, None, None
    axis = (normals[stack] * np.sign(normals[stack] @ normals[stack[0]])[:, None]).mean(axis=0)
    axis = axis / np.linalg.norm(axis)   # the mean normal of the stack
    heights = np.array([planes[numbers[i]].centre @ axis for i in stack])
    apex = np.isin(labels, BIVME_APEX)
    if apex.any():
        toward_base = np.sign(heights.mean() - points[apex].mean(axis=0) @ axis) or 1.0
    else:
        endo = np.isin(labels, BIVME_SURFACES["LV_ENDO"])
        widths = []
        for i in stack:
            members = points[endo & (slices == numbers[i])]
            widths.append(np.linalg.norm(members - members.mean(axis=0), axis=1).mean() if len(members) else 0.0)
        toward_base = np.sign(np.polyfit(heights, widths, 1)[0]) or 1.0
    return axis * toward_base, [numbers[i] for i in stack], heights * toward_base


def check_heart(mesh, function, radius: float, fidelity, *, scale: float = 1.0,
                allow_implausible: bool = False) -> list:
    """What a cardiac user checks on a myocardium mesh; raise :class:`MeshingError` naming what failed (a
    :class:`BitemeshWarning` with ``allow_implausible``).

    - each cavity (LV_ENDO, RV_ENDO) not filled: at most 10 % of the mesh's cells whose centroids lie deeper than
      max(min_wall, R) + 1 mm inside a cavity, by volume of the cavity;
    - each cavity open at the base: at least half of its section 1 mm below the base outside the mesh (its core,
      deeper than min_wall: the walls are kept at least that thick, narrowing the cavity by as much);
    - the myocardial volume and the mean wall thickness (2 x volume / walls' area) in :data:`MYOCARDIAL_VOLUME`
      and :data:`WALL_THICKNESS`, their lower ends times ``scale`` cubed and ``scale`` (the heart's
      :func:`heart_scale`);
    - the guide points near the boundary: mean <= 0.5 x noise + R / 4 and 95th percentile <= noise + R (the
      tracing noise, and a linear boundary of edges R);
    - no cavity open through its wall below the base (:data:`OPENING`);
    - and, as a warning only, a boundary of genus 0 (a myocardium open at the base has no handle).

    Parameters
    ----------
    mesh : Mesh in mm (cell data Volume); function : the LabelledImplicit (mm); radius : R (mm)
    fidelity : the Fidelity measured on the mesh (or None); scale : the heart's size against an adult's, <= 1

    Returns
    -------
    list of the problems (empty when plausible)
    """
    from ...mesh.simplicial import facet_measures
    from ...mesh.validity import count_boundary_components
    from ...mesh.topology import boundary_facets, euler_characteristic

    points, cells = np.asarray(mesh.points), np.asarray(mesh.cells)
    volumes = np.asarray(mesh.cell_data["Volume"])
    centroids = points[cells].mean(axis=1)
    problems = []
    for name in ("LV_ENDO", "RV_ENDO"):
        if name not in function.surfaces:
            continue
        cavity = function.surfaces[name]
        depth = max(function.min_wall, radius) + 1.0
        filled = volumes[cavity(centroids) > depth].sum()
        section = _cavity_section(cavity, function.base, core=function.min_wall)
        if len(section):
            inside_mesh = np.asarray(function(section)) > 0
            if inside_mesh.mean() > 0.5:
                problems.append(f"the {name} cavity is closed at the base: {inside_mesh.mean():.0%} of its section "
                                "1 mm below the base is myocardium")
        volume = cavity.inside_volume() if function.base is None else _volume_below(cavity, function.base)
        if volume > 0 and filled > 0.1 * volume:
            problems.append(f"the {name} cavity is filled: {filled / 1000:.1f} ml of cells lie deeper than "
                            f"{depth:.1f} mm inside it ({filled / volume:.0%} of its {volume / 1000:.1f} ml)")
    total = float(volumes.sum())
    facets = boundary_facets(cells)
    corners = points[facets]
    areas = facet_measures(corners)
    walls = areas[~function.is_base(corners.mean(axis=1))].sum() if function.base is not None else areas.sum()
    thickness = 2 * total / walls if walls > 0 else np.inf
    low, high = MYOCARDIAL_VOLUME
    if not low * scale ** 3 <= total / 1000 <= high:
        problems.append(f"the myocardial volume {total / 1000:.3g} ml is outside [{low * scale ** 3:.3g}, {high:g}] ml")
    low, high = WALL_THICKNESS
    if not low * scale <= thickness <= high:
        problems.append(f"the mean wall thickness {thickness:.2g} mm is outside [{low * scale:.2g}, {high:g}] mm")
    if function.base is not None and mesh.facets is not None:
        problems += _openings_beside_base(mesh, function, radius)
    euler = euler_characteristic(facets)
    handles = (2 * count_boundary_components(mesh) - euler) // 2
    if handles > 0:
        warnings.warn(f"the heart mesh's boundary has {handles} handle(s) (Euler characteristic {euler}): a tunnel "
                      "through a wall, or a bridge across a cavity, that no cut or fill of cells thinner than two "
                      "cells removes (with handles = 'keep', none is removed); check the contours where the fitted "
                      "surfaces meet, or try a smaller radius", BitemeshWarning, stacklevel=2)
    if fidelity is not None and fidelity.samples:
        mean_bound, p95_bound = 0.5 * fidelity.noise + radius / 4, fidelity.noise + radius
        if fidelity.to_boundary_mean > mean_bound or fidelity.to_boundary_p95 > p95_bound:
            problems.append(f"the guide points lie {fidelity.to_boundary_mean:.2f} mm (mean) and "
                            f"{fidelity.to_boundary_p95:.2f} mm (95 %) from the boundary, beyond {mean_bound:.2f} and "
                            f"{p95_bound:.2f} mm (0.5 x noise + R/4, noise + R)")
    if problems:
        text = ("the heart mesh is not plausible: " + "; ".join(problems) + f" (R = {radius:.2f} mm, "
                f"{len(cells)} cells). Check the labels and the contours, give a smaller radius, or set "
                "allow_implausible (--allow-implausible) to keep the mesh anyway")
        if not allow_implausible:
            raise MeshingError(text)
        warnings.warn(text, BitemeshWarning, stacklevel=2)
    return problems


def _openings_beside_base(mesh, function, radius: float) -> list:
    """A problem for each cavity whose endocardium meets the epicardium more than the rim of the openings and a cell
    below the base along more than :data:`OPENING` x R: where, how long, how deep."""
    depth = function.rim + radius
    problems = []
    for name in ENDOCARDIAL_TAGS:
        rim = opening_lips(mesh, function.base.below, depth, (name,))
        length = _length(mesh.points, rim)
        if length > OPENING * radius:
            ends = mesh.points[rim].reshape(-1, 3)
            centre = ", ".join(f"{value:.1f}" for value in ends.mean(axis=0))
            problems.append(
                f"the {name} cavity opens through its wall beside the base: its endocardium meets the epicardium "
                f"along {length:.0f} mm more than {depth:.1f} mm below the base, around ({centre}), down to "
                f"{function.base.below(ends).max():.0f} mm (allowed {OPENING * radius:.0f} mm, {OPENING:g} R); check "
                f"the {name} and epicardial contours near there (a contour of the wrong surface, or slices of another "
                "breath-hold, make the cavity's surface run through the epicardium's)")
    return problems


def opening_beside_base(mesh, below, depth: float, cavities=tuple(ENDOCARDIAL_TAGS)) -> float:
    """How long (input units) the endocardium of ``cavities`` meets the epicardium more than ``depth`` below the base
    (:func:`opening_lips`); 0 on a heart whose cavities open through the base alone."""
    return _length(mesh.points, opening_lips(mesh, below, depth, cavities))


def _length(points: np.ndarray, edges: np.ndarray) -> float:
    """The summed length of ``edges`` (e, 2) point ids into ``points`` (n, 3)."""
    return float(np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1).sum())


def opening_lips(mesh, below, depth: float, cavities=tuple(ENDOCARDIAL_TAGS)) -> np.ndarray:
    """(e, 2) the edges (point ids) where the endocardium of ``cavities`` meets the epicardium more than ``depth``
    below the base (:func:`~bitemesh.core.mesh.tags.lips`: the rim of an opening that is not the base); ``mesh``
    tagged, ``below`` (m, 3) -> (m,) the depth below its base.  An edge is as deep as its shallower end: ``below`` is
    about a distance, which changes by at most an edge's length along it, but the base's stretch jumps across the
    edges of its height field's triangles (an edge 4.3 and 5.8 mm below the base at its ends measured 7.9 at its
    middle)."""
    from ...mesh.tags import lips

    rim = lips(mesh, [tag for cavity in cavities for tag in ENDOCARDIAL_TAGS[cavity]], EPICARDIAL_TAGS)
    return rim[below(mesh.points[rim.reshape(-1)]).reshape(-1, 2).min(axis=1) > depth] if len(rim) else rim


def _volume_below(grid, base) -> float:
    """The volume (input units^3) of {f > 0} below the base, counted on the grid's nodes."""
    inside = np.flatnonzero(grid.values.reshape(-1) > 0)
    return float(np.count_nonzero(base.below(grid.node_coordinates(inside)) > 0) * np.prod(grid.spacing))


def _cavity_section(grid, base, depth: float = 1.0, core: float = 0.0) -> np.ndarray:
    """(m, 3) the nodes of the cavity's grid with f > ``core`` (deeper than the thinnest wall the domain keeps, which
    may narrow the cavity by that much) within one spacing of the surface ``depth`` below the base."""
    if base is None:
        return np.zeros((0, 3))
    nodes = grid.node_coordinates(np.flatnonzero(grid.values.reshape(-1) > core))
    return nodes[np.abs(base.below(nodes) - depth) < grid.spacing.max()]


def time_frame(frames, slices, frame, where: str, how: str):
    """(n,) bool, the points of time frame ``frame`` (None: every point, returned as None).

    Without ``frame``, points of several frames are refused when a slice holds more than one of them (the same
    slice traced at several phases); biv-me writes one file per frame, and a slice of another series may number it
    otherwise, which stays.  ``where`` names the input and ``how`` the way to choose a frame in the messages.

    Parameters
    ----------
    frames : (n,) float64 time frame per point, or None (no such column); slices : (n,) int or None
    """
    if frame is None:
        if frames is None or len(np.unique(frames)) < 2:
            return None
        several = (slices is None
                   or any(len(np.unique(frames[slices == number])) > 1 for number in np.unique(slices)))
        if not several:
            return None
        counts = ", ".join(f"{value:g} ({count} points)"
                           for value, count in zip(*np.unique(frames, return_counts=True)))
        raise InvalidInputError(f"{where} holds several time frames ({counts}), some slices traced at more than one; "
                                f"choose one with {how}")
    frame = check_number(frame, "frame")
    if frames is None:
        raise InvalidInputError(f"frame = {frame:g}: {where} has no time-frame column ('time frame', 'time' or "
                                "'phase'); leave frame out")
    keep = frames == frame
    if not keep.any():
        values = ", ".join(f"{value:g}" for value in np.unique(frames))
        raise InvalidInputError(f"frame = {frame:g}: {where} holds no point of that time frame; its frames: {values}")
    if not keep.all():
        logging.getLogger("bitemesh").info("%s: time frame %g, %d of %d points", where, frame, int(keep.sum()),
                                           len(keep))
    if slices is not None:
        missing = sorted(set(np.unique(slices[~keep]).tolist()) - set(np.unique(slices[keep]).tolist()))
        if missing:
            listed = ", ".join("slice {} (frames {})".format(number, ", ".join(
                map("{:g}".format, np.unique(frames[slices == number])))) for number in missing[:6])
            warnings.warn(BitemeshWarning(
                f"{where}: {len(missing)} slice(s) hold no point of time frame {frame:g} and are left out: {listed}; "
                "a series that numbers its frames otherwise (biv-me writes 1 for its three-chamber view) cannot be "
                "told apart in a file of several frames: give each frame its own file"), stacklevel=2)
    return keep
