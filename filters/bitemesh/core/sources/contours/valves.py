"""The valves of biv-me contours: where each cavity opens (a point inside it at each valve's centre), and the
contour points traced across a valve rather than along a wall.

Some exports trace a long-axis contour as a closed loop, its last stretch straight across the valve between the two
annulus points of that view: those points sample no wall (the cavity opens there), and a fit through them would close
the cavity at the base.  They are left out, with a note: the points of a wall contour within :data:`ACROSS` of the
chord between a valve's two points of the same slice, along its inner :data:`INNER` share.
"""
from __future__ import annotations

import numpy as np

from .cardiac import BIVME_VALVES

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
