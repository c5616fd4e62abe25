"""The surface that closes a heart's domain at the base: through the valve annuli where the data puts them, or a
plane (a user's, the least-squares plane of the valve points, or the basal short-axis slice).

On real hearts the annuli are not coplanar: the mitral annulus is tilted against the short-axis stack, the aortic
and pulmonary valves sit higher than the mitral and tricuspid, and the long-axis contours run up to each.  A plane
through the valves' centres cuts the basal myocardium off (guide points 10 to 18 mm above the mesh).  So the base of
biv-me contours is a height field over the short-axis plane, h(u, v), a thin-plate spline (the 2D polyharmonic RBF
of :mod:`bitemesh.core.rbf`, lightly smoothed) through the valve points and the upper ends of the long-axis wall
contours (:func:`annulus_points`): the myocardium reaches each annulus, and the cap between them is the smoothest
surface through them.  Its value, (h(u, v) - height) / sqrt(1 + |grad h|^2), is about the distance below it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from ..errors import InvalidInputError, check_choice, check_points
from ..rbf import RBFImplicit, fit_partition
from .cardiac import BIVME_APEX, BIVME_SURFACES, BIVME_VALVES, is_bivme, short_axis_stack
from .slices import GAP_FACTOR, is_closed, polylines

#: smoothing of the base's thin-plate spline (in units of its kernel at the constraints' diameter): the valve
#: points and contour ends of neighbouring slices disagree by a millimetre or two, which it averages.
BASE_SMOOTHING = 1e-3
#: the base is raised over the wall points it leaves above it by more than this (mm), the highest of them at most
#: this many rounds, no two new anchors closer than this spacing (mm).
ENVELOPE_TOLERANCE, ENVELOPE_ROUNDS, ENVELOPE_SPACING = 1.0, 4, 10.0
#: an end of a long-axis contour is an annulus point when it lies above the basal short-axis slice by at least
#: this (mm): the contour's other end is at the apex.
ABOVE_BASAL_SLICE = 0.0


@dataclass(frozen=True, eq=False)
class BaseSurface:
    """The base: the points x with height (x - point) . normal = h(u, v), (u, v) = (x - point) . axes.

    Attributes
    ----------
    point : (3,) float64, a point of the base plane the heights are measured from (input units)
    normal : (3,) float64 unit, out of the domain (away from the apex)
    axes : (2, 3) float64, orthonormal in-plane axes (u, v)
    heights : the height field h(u, v) (a 2D RBF, input units), or None for the plane itself
    """

    point: np.ndarray
    normal: np.ndarray
    axes: np.ndarray
    heights: Optional[RBFImplicit] = None

    @classmethod
    def plane(cls, point, normal) -> "BaseSurface":
        """The plane through ``point`` (3,) with unit ``normal`` (3,) out of the domain."""
        point, normal = np.asarray(point, dtype=np.float64), np.asarray(normal, dtype=np.float64)
        normal = normal / np.linalg.norm(normal)
        first = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        first /= np.linalg.norm(first)
        return cls(point, normal, np.array([first, np.cross(normal, first)]))

    @property
    def is_plane(self) -> bool:
        return self.heights is None

    def below(self, x) -> np.ndarray:
        """(m,) about the distance of (m, 3) points below the base (> 0 on the domain's side), input units."""
        offset = np.asarray(x, dtype=np.float64) - self.point
        height = offset @ self.normal
        if self.heights is None:
            return -height
        in_plane = offset @ self.axes.T
        slope = self.heights.gradient(in_plane)
        return (self.heights(in_plane) - height) / np.sqrt(1.0 + np.einsum("ij,ij->i", slope, slope))

    def outward(self, x) -> np.ndarray:
        """(m, 3) unit normals of the base at (m, 3) points' (u, v), pointing out of the domain."""
        offset = np.asarray(x, dtype=np.float64) - self.point
        if self.heights is None:
            return np.broadcast_to(self.normal, offset.shape).copy()
        direction = self.normal - self.heights.gradient(offset @ self.axes.T) @ self.axes
        return direction / np.linalg.norm(direction, axis=1, keepdims=True)

    def moved(self, shift) -> "BaseSurface":
        """The same surface translated by ``shift`` (3,)."""
        return replace(self, point=self.point + np.asarray(shift, dtype=np.float64))

    def raised(self, distance: float) -> "BaseSurface":
        """The same surface moved ``distance`` along its normal (> 0: away from the apex)."""
        return self.moved(float(distance) * self.normal)


def fit_base_plane(valve_points, inside_point) -> BaseSurface:
    """The least-squares plane of the valve points, its normal pointing away from ``inside_point`` (the apex)."""
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
    return BaseSurface.plane(centre, normal)


def annulus_points(points, labels, slices, planes, axis, floor: float) -> np.ndarray:
    """(k, 3) the points the base passes through: every valve point, and each end of a long-axis wall contour
    (the longest paths of its points in its slice, :func:`~bitemesh.core.contours.slices.polylines`) that lies
    higher than ``floor`` along ``axis`` (its other end is at the apex; a closed contour has no end)."""
    chosen = [points[np.isin(labels, BIVME_VALVES)]]
    wall = {label for members in BIVME_SURFACES.values() for label in members if label.startswith("LAX_")}
    for label in sorted(wall & set(np.unique(labels).tolist())):
        for number in np.unique(slices[(labels == label) & (slices >= 0)]).tolist():
            members = np.flatnonzero((labels == label) & (slices == number))
            if number not in planes or len(members) < 3:
                continue
            paths, _, spacing = polylines(planes[number].project(points[members]), GAP_FACTOR)
            for path in paths:
                if len(path) > 3 and not is_closed(planes[number].project(points[members]), path, spacing, GAP_FACTOR):
                    ends = points[members[[path[0], path[-1]]]]
                    chosen.append(ends[ends @ axis > floor])
    return np.vstack(chosen)


def annulus_surface(points, labels, slices, planes, smoothing: float = BASE_SMOOTHING):
    """The base of biv-me contours (see the module docstring), and a note; None (and a note) without valve points
    and long-axis contour ends, or without a short-axis stack to measure heights along."""
    axis, numbers, heights = short_axis_stack(points, labels, slices, planes)
    if axis is None:
        return None, ()
    basal = int(np.argmax(heights))
    anchors = annulus_points(points, labels, slices, planes, axis, heights[basal] + ABOVE_BASAL_SLICE)
    if len(anchors) < 3:
        return BaseSurface.plane(planes[numbers[basal]].centre, axis), (
            f"no valve points or long-axis contours above the basal short-axis slice: the base is that slice's "
            f"plane (slice {numbers[basal]})",)
    base = BaseSurface.plane(anchors.mean(axis=0), axis)
    wall = points[np.isin(labels, [label for members in BIVME_SURFACES.values() for label in members])]
    for _ in range(ENVELOPE_ROUNDS):
        in_plane = (anchors - base.point) @ base.axes.T
        spread = np.linalg.svd(in_plane - in_plane.mean(axis=0), compute_uv=False)
        if spread[1] <= 0.05 * spread[0]:   # on one line: only the plane through them, perpendicular to the stack
            return base, ()
        diameter = float(np.linalg.norm(np.ptp(in_plane, axis=0)))
        field = fit_partition(in_plane, (anchors - base.point) @ axis, kernel="thin_plate", smoothing=smoothing,
                              frame=(in_plane.mean(axis=0), diameter), what=f"{len(anchors)} annulus points")
        surface = replace(base, heights=field)
        above = wall[surface.below(wall) < -ENVELOPE_TOLERANCE]
        if not len(above):
            break
        anchors = np.vstack([anchors, above[_highest_apart(above, axis, ENVELOPE_SPACING)]])
    return surface, ()


def _highest_apart(points, axis, spacing: float) -> np.ndarray:
    """Indices of the highest of (m, 3) points along ``axis``, greedily, no two closer than ``spacing``."""
    order = np.argsort(-(points @ axis), kind="stable")
    chosen = []
    for index in order:
        if all(np.linalg.norm(points[index] - points[other]) >= spacing for other in chosen):
            chosen.append(index)
    return np.array(chosen, dtype=np.int64)


def choose_base(base_plane, points, labels, surface_points, slices, planes):
    """The :class:`BaseSurface` that ``base_plane`` asks for, or None; and a note."""
    if base_plane is None or (isinstance(base_plane, str) and base_plane == "none"):
        return None, ()
    if isinstance(base_plane, str):
        check_choice(base_plane, "base_plane", ("auto", "valves", "none"))
        valves = np.isin(labels, BIVME_VALVES)
        if is_bivme(labels) and (base_plane == "auto" or valves.sum() >= 3):
            base, notes = annulus_surface(points, labels, slices, planes)
            if base is not None or valves.sum() < 3:
                return base, notes
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
    return BaseSurface.plane(point, normal), ()
