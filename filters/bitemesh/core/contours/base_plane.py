"""The base plane that closes a heart's domain: the plane of the valve points, biv-me's plane through the valves'
centres (:func:`bitemesh.core.contours.cardiac.base_plane`), or a user's (point, normal)."""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError, check_choice, check_points
from .cardiac import BIVME_APEX, BIVME_VALVES, is_bivme
from .cardiac import base_plane as cardiac_base_plane


def fit_base_plane(valve_points, inside_point):
    """The least-squares plane of the valve points, its normal pointing away from ``inside_point`` (the apex).

    Returns
    -------
    point : (3,) the valve points' centroid; normal : (3,) unit, out of the domain
    """
    valve_points = check_points(valve_points, "valve points", dims=(3,))
    if len(valve_points) < 3:
        raise InvalidInputError(f"a base plane needs at least 3 valve points, got {len(valve_points)}")
    centre = valve_points.mean(axis=0)
    _, spread, axes = np.linalg.svd(valve_points - centre, full_matrices=False)
    if spread[1] <= 1e-6 * spread[0]:
        raise InvalidInputError(f"the {len(valve_points)} valve points lie on one line, so they give no base plane; "
                                "give base_plane=(point, normal)")
    normal = axes[2]
    if (np.asarray(inside_point, float) - centre) @ normal > 0:
        normal = -normal
    return centre, normal


def choose_base_plane(base_plane, points, labels, surface_points, slices, planes):
    """(point, normal) of the base plane, or None; and a note."""
    if base_plane is None or (isinstance(base_plane, str) and base_plane == "none"):
        return None, ()
    if isinstance(base_plane, str):
        check_choice(base_plane, "base_plane", ("auto", "valves", "none"))
        valves = np.isin(labels, BIVME_VALVES)
        if is_bivme(labels) and (base_plane == "auto" or valves.sum() >= 3):
            plane, notes = cardiac_base_plane(points, labels, slices, planes)
            if plane is not None or valves.sum() < 3:
                return plane, notes
        elif base_plane == "auto" and valves.sum() < 3:
            return None, ()
        if valves.sum() < 3:
            raise InvalidInputError(
                f"base_plane='valves' needs at least 3 points labelled {', '.join(BIVME_VALVES)}; the input has "
                f"{int(valves.sum())}; give base_plane=(point, normal) or base_plane=None")
        apex = np.isin(labels, BIVME_APEX)
        inside = points[apex].mean(axis=0) if apex.any() else surface_points.mean(axis=0)
        return fit_base_plane(points[valves], inside), ()
    try:
        point, normal = (np.asarray(part, dtype=np.float64) for part in base_plane)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"base_plane must be 'valves', 'auto', None or (point, normal), got {base_plane!r}") from None
    if point.shape != (3,) or normal.shape != (3,) or not np.isfinite(point).all() or not np.isfinite(normal).all() \
            or not np.linalg.norm(normal) > 0:
        raise InvalidInputError(f"base_plane (point, normal) needs two finite 3-vectors, the normal nonzero (it "
                                f"points out of the domain), got {base_plane!r}")
    return (point, normal / np.linalg.norm(normal)), ()

