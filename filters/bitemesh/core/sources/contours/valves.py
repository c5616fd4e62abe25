"""The valves of biv-me contours: where each cavity opens (a point inside it at each valve's centre), the inflow
rings as samples of the cavities' walls, the contour points traced across a valve rather than along a wall, and the
ring points a mesh leaves (:func:`rings_off_the_mesh`).

Some exports trace a long-axis contour as a closed loop, its last stretch straight across the valve between the two
annulus points of that view: those points sample no wall (the cavity opens there), and a fit through them would close
the cavity at the base.  They are left out, with a note: the points of a wall contour within :data:`ACROSS` of the
chord between a valve's two points of the same slice, along its inner :data:`INNER` share.
"""
from __future__ import annotations

import numpy as np

from .cardiac import BIVME_SURFACES, BIVME_VALVES

#: the cavities whose inflow valve points are samples of their walls too (an outflow ring as well would fold the
#: wall between the two rings into the cavity: a bridge of myocardium across it).
CAVITY_RINGS = {"LV_ENDO": ("MITRAL_VALVE",), "RV_ENDO": ("TRICUSPID_VALVE",)}
INFLOW_RINGS = tuple(valve for valves in CAVITY_RINGS.values() for valve in valves)

#: a contour point within this (mm) of a valve's chord is traced across the valve.
ACROSS = 3.0
#: along the chord's middle share (its ends are the annulus, where the wall is).
INNER = (0.1, 0.9)


def outlet_points(points, labels, valves, wall: float = 0.0):
    """Per valve label present: the centre of its points and its radius (mean distance of its points to it) plus
    ``wall``; None without any."""
    centres, radii = [], []
    for valve in valves:
        members = points[labels == valve]
        if len(members) >= 2:
            centre = members.mean(axis=0)
            centres.append(centre)
            radii.append(float(np.linalg.norm(members - centre, axis=1).mean()) + wall)
    return (np.array(centres), np.array(radii)) if centres else None


def annulus_normals(points, labels) -> np.ndarray:
    """(n, 3) the outward normals of a cavity's wall at its valve points (n, 3): each point's direction from its
    valve's centre in the valve's plane (the least-squares plane of its points).  NaN for a valve of fewer than three
    points (seen in one view: its chord's middle is no centre of a ring that is not a circle) and at a centre."""
    normals = np.full(np.shape(points), np.nan)
    for valve in np.unique(labels).tolist():
        members = labels == valve
        radial = points[members] - points[members].mean(axis=0)
        if members.sum() < 3:
            continue
        axis = np.linalg.svd(radial, full_matrices=False)[2][2]
        radial = radial - np.outer(radial @ axis, axis)
        length = np.linalg.norm(radial, axis=1, keepdims=True)
        away = length > 1e-6 * max(float(length.max()), 1e-300)
        normals[members] = np.where(away, radial / np.maximum(length, 1e-300), np.nan)
    return normals


def ring_normals(rings, ring_labels, ring_slices, wall, wall_slices, wall_normals) -> np.ndarray:
    """(n, 3) the outward normals of a cavity's wall at its inflow valve points ``rings`` (n, 3):
    :func:`annulus_normals`, and for a valve seen in one view only (fewer than three points) the in-plane normal of
    the nearest point of the cavity's contours ``wall`` (m, 3) in the same slice (``wall_normals`` (m, 3), NaN where
    none): the contour runs on from the annulus, so its last normals are the wall's there.  NaN where neither is
    known."""
    normals = annulus_normals(rings, ring_labels)
    known = np.isfinite(wall_normals).all(axis=1)
    for row in np.flatnonzero(np.isnan(normals).any(axis=1)):
        same = np.flatnonzero(known & (wall_slices == ring_slices[row]))
        if ring_slices[row] >= 0 and len(same):
            normals[row] = wall_normals[same[np.argmin(np.linalg.norm(wall[same] - rings[row], axis=1))]]
    return normals


#: a cavity's fit that runs on past a ring point (a pocket behind it, under a fin of wall thinner than a cell that
#: the mesh loses) is held outside along the ring's normal up to its wall when that wall lies within this (mm); a
#: point farther from any wall is no annulus of that cavity's (named by :func:`rings_off_the_mesh`), and a wall
#: forced there would cut across the cavity.
POCKET_REACH = 10.0
#: the step (mm) of the profile along the normal.
POCKET_STEP = 0.5


def walls_behind(cavity, rings, normals, wall: float) -> tuple:
    """Interior values that leave a wall behind each ring point: where the fit ``cavity`` ((m, 3) -> (m,), > 0
    inside) is inside again within :data:`POCKET_REACH` of a ring point (n, 3) along its normal (n, 3; NaN: none),
    before its wall (where it stays outside for twice ``wall`` mm: a fin of one wall's thickness between the cavity
    and a pocket behind it is what the mesh loses), the pocket's points every other POCKET_STEP, valued minus their
    distance from the ring point up to ``wall`` (about the signed distance of a wall behind it).

    Returns ((j, 3) points, (j,) values), empty when no ring point has a pocket."""
    thick = int(round(2 * wall / POCKET_STEP))
    steps = POCKET_STEP * np.arange(1, int(round(POCKET_REACH / POCKET_STEP)) + thick + 1)
    centres, values = [], []
    for point, normal in zip(rings, normals):
        if not np.isfinite(normal).all():
            continue
        profile = cavity(point + np.outer(steps, normal))
        outside = profile <= 0
        run = np.convolve(outside, np.ones(thick), "valid") == thick   # a wall starts at each True
        start = int(np.argmax(run))
        if not run[start] or steps[start] > POCKET_REACH or not (profile[:start] > 0).any():
            continue   # no wall within reach, or no pocket before it
        pocket = steps[:start][profile[:start] > 0][::2]   # 1 mm apart, beyond the fit's own off-surface points
        centres.append(point + np.outer(pocket, normal))
        values.append(-np.minimum(pocket, wall))
    if not centres:
        return np.zeros((0, 3)), np.zeros(0)
    return np.vstack(centres), np.concatenate(values)


def across_valves(points, labels, slices, wall_labels):
    """(n,) bool, the points of ``wall_labels`` traced across a valve (see the module docstring), and a note."""
    across = np.zeros(len(points), bool)
    counts = {}
    for valve in BIVME_VALVES:
        for number in np.unique(slices[(labels == valve) & (slices >= 0)]).tolist():
            ends = points[(labels == valve) & (slices == number)]
            if len(ends) != 2:
                continue
            chord = ends[1] - ends[0]
            members = np.flatnonzero((slices == number) & np.isin(labels, wall_labels))
            t = (points[members] - ends[0]) @ chord / max(float(chord @ chord), 1e-300)
            distance = np.linalg.norm(points[members] - ends[0] - t[:, None] * chord, axis=1)
            hit = members[(distance < ACROSS) & (t > INNER[0]) & (t < INNER[1])]
            across[hit] = True
            for label in np.unique(labels[hit]).tolist():
                key = (label, valve)
                counts[key] = counts.get(key, 0) + int(np.count_nonzero(labels[hit] == label))
    if not counts:
        return across, ()
    return across, ("points traced across a valve left out (no wall there: the cavity opens): "
                    + ", ".join(f"{count} {label} across the {valve.split('_')[0].lower()} valve"
                                for (label, valve), count in counts.items()),)


def rings_off_the_mesh(distances, points, labels, slices, bound: float) -> tuple:
    """Notes on the inflow ring points farther than ``bound`` (mm) from the mesh, ``distances`` (n,) being each of
    ``points`` (n, 3) (labels, slices (n,)) to the mesh's boundary: each with its nearest contour point of its
    cavity's wall in its own slice, so that a ring point placed away from the wall its view traces (inside the
    cavity, beyond the contours' ends) is named rather than followed into a wall no contour shows.  Empty when none."""
    notes = []
    for cavity, valves in CAVITY_RINGS.items():
        wall = np.isin(labels, BIVME_SURFACES[cavity])
        for row in np.flatnonzero(np.isin(labels, valves) & (distances > bound)):
            same = wall & (slices == slices[row]) & (slices[row] >= 0)
            gap = np.linalg.norm(points[same] - points[row], axis=1).min() if same.any() else None
            reach = "" if gap is None else f"; its slice's {cavity} contours end {gap:.1f} mm from it"
            notes.append(f"the {labels[row]} point at ({', '.join(f'{value:.1f}' for value in points[row])}) (slice "
                         f"{slices[row]}) lies {distances[row]:.1f} mm from the mesh, beyond R + the tracing noise "
                         f"({bound:.1f} mm){reach}: the mesh follows the walls the contours trace; if the annulus is "
                         "there, trace the contours up to it, or check the point's slice")
    return tuple(notes)
