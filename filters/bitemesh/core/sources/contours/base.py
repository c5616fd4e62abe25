"""The surface that closes a heart's domain at the base: through the valve annuli where the data puts them, or a
plane (a user's, the least-squares plane of the valve points, or the basal short-axis slice).

On real hearts the annuli are not coplanar: the mitral annulus is tilted against the short-axis stack, the aortic
and pulmonary valves sit higher than the mitral and tricuspid, and the long-axis contours run up to each.  A plane
through the valves' centres cuts the basal myocardium off (guide points 10 to 18 mm above the mesh).  So the base of
biv-me contours is a height field over the short-axis plane, h(u, v), through the valve points and the upper ends of
the long-axis wall contours (:func:`annulus_points`), 2 mm above the valve points and 1 mm above the contours' ends,
and over every wall guide point, staying as high within a wall's thickness of each (:func:`_plateau`): the
myocardium reaches each annulus.  Between them h is linear on the Delaunay triangles of those anchors
(:class:`PiecewiseLinear`): a smooth interpolant (a thin-plate spline) through annulus points a few millimetres
apart at heights 10 mm apart swings 20-30 mm beyond them, and does so differently for the same contours sampled more
densely; a linear one stays between them.  Its value, (h(u, v) - height) /
sqrt(1 + |grad h|^2), is about the distance below it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Optional

import numpy as np

from scipy.spatial import Delaunay, cKDTree

from ...errors import InvalidInputError, check_choice, check_points
from .cardiac import BIVME_APEX, BIVME_SURFACES, BIVME_VALVES, is_bivme, short_axis_stack
from .slices import GAP_FACTOR, is_closed, polylines

#: the anchors' triangulation reaches this many times their extent from their centre, by a ring of anchors at the
#: heights of the nearest ones (h is flat beyond the annuli).
RING_REACH, RING_ANCHORS = 3.0, 36
#: the base passes this far (mm) above its annulus points, half the default R (2 mm): a long-axis contour's end then
#: lies on its wall just below the base, where the mesh follows it, not on the rim the mesh rounds off.
ABOVE_ANNULUS = 1.0
#: and this far above its valve points, the default R: the wall tapers to the annulus (the epicardium meets the
#: endocardium there), and 1 mm left a wedge thinner than a cell between the base and the epicardium, which the mesh
#: lost for up to 6 mm beside a mitral annulus point (biv-me patient1, frame 15: 6.3 mm, now 1.7).  The whole base
#: 2 mm higher brings every frame's mitral points within 3.1 mm but moves the myocardium's volume by up to 3 % for
#: a small change of the input (the grid I follows the base), where 1 mm keeps it within 0.1 %.
ABOVE_VALVES = 2.0
#: the base is raised over each wall and valve point it passes less than its height above it (ABOVE_ANNULUS,
#: ABOVE_VALVES) minus this (mm) above, at most this many rounds; of the annulus points it starts from, the highest
#: of those within this distance (mm) of each other in the base's plane (:func:`_highest_within`).
ENVELOPE_TOLERANCE, ENVELOPE_ROUNDS, ANCHOR_CELL = 0.5, 4, 5.0
#: a point the base passes too near gets an anchor of its own, or raises one nearer than this (mm) in the plane.
ANCHOR_MERGE = 1.0
#: the base stays at an anchor's height or above within this (mm) of it in its plane: the thinnest wall.
PLATEAU = 2.5
#: the anchor such a point gets stands its clearance over the cosine of the base's slope there above it (the slope
#: counted up to 60 deg).
STEEPEST = 2.0


@dataclass(frozen=True, eq=False)
class BaseSurface:
    """The base: the points x with height (x - point) . normal = h(u, v), (u, v) = (x - point) . axes.

    Attributes
    ----------
    point : (3,) float64, a point of the base plane the heights are measured from (input units)
    normal : (3,) float64 unit, out of the domain (away from the apex)
    axes : (2, 3) float64, orthonormal in-plane axes (u, v)
    heights : the height field h(u, v) (:class:`PiecewiseLinear`, input units), or None for the plane itself
    """

    point: np.ndarray
    normal: np.ndarray
    axes: np.ndarray
    heights: Optional["PiecewiseLinear"] = None

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
        value, slope = self.heights.value_and_gradient(offset @ self.axes.T)
        return (value - height) / np.sqrt(1.0 + np.einsum("ij,ij->i", slope, slope))

    def outward(self, x) -> np.ndarray:
        """(m, 3) unit normals of the base at (m, 3) points' (u, v), pointing out of the domain."""
        offset = np.asarray(x, dtype=np.float64) - self.point
        if self.heights is None:
            return np.broadcast_to(self.normal, offset.shape).copy()
        direction = self.normal - self.heights.gradient(offset @ self.axes.T) @ self.axes
        return direction / np.linalg.norm(direction, axis=1, keepdims=True)

    def mapped(self, scale: float, shift) -> "BaseSurface":
        """The same surface in the coordinates x * ``scale`` + ``shift`` (3,)."""
        heights = self.heights if self.heights is None or scale == 1 else \
            PiecewiseLinear(self.heights.anchors * scale, self.heights.heights * scale)
        return replace(self, point=self.point * scale + np.asarray(shift, dtype=np.float64), heights=heights)

    def raised(self, distance: float) -> "BaseSurface":
        """The same surface moved ``distance`` along its normal (> 0: away from the apex)."""
        return replace(self, point=self.point + float(distance) * self.normal)


@dataclass(frozen=True, eq=False)
class PiecewiseLinear:
    """h(u, v), linear on the Delaunay triangles of anchors (k, 2) with heights (k,), extended by a ring of anchors
    far beyond them at the heights of the nearest (:data:`RING_REACH`), flat beyond the ring."""

    anchors: np.ndarray
    heights: np.ndarray

    @classmethod
    def through(cls, anchors, heights) -> "PiecewiseLinear":
        centre = anchors.mean(axis=0)
        reach = RING_REACH * float(np.linalg.norm(anchors - centre, axis=1).max())
        angle = np.linspace(0.0, 2 * np.pi, RING_ANCHORS, endpoint=False)
        ring = centre + reach * np.column_stack([np.cos(angle), np.sin(angle)])
        nearest = cKDTree(anchors).query(ring)[1]
        return cls(np.vstack([anchors, ring]), np.r_[heights, heights[nearest]])

    @cached_property
    def _triangles(self) -> Delaunay:
        return Delaunay(self.anchors)

    @cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.anchors)

    def _weights(self, uv):
        """The triangle of each of (m, 2) points (-1 beyond the ring) and its barycentric weights (m, 3)."""
        mesh = self._triangles
        uv = np.asarray(uv, dtype=np.float64)
        simplex = mesh.find_simplex(uv)
        transform = mesh.transform[np.maximum(simplex, 0)]
        first = np.einsum("mij,mj->mi", transform[:, :2], uv - transform[:, 2])
        return mesh, simplex, np.column_stack([first, 1.0 - first.sum(axis=1)])

    def value_and_gradient(self, uv) -> tuple:
        """(m,) h and (m, 2) grad h at (m, 2) points, from one point location: each triangle's; beyond the ring the
        nearest anchor's height, slope 0."""
        uv = np.asarray(uv, dtype=np.float64)
        mesh, simplex, weights = self._weights(uv)
        outside = simplex < 0
        corner = self.heights[mesh.simplices[np.maximum(simplex, 0)]]   # (m, 3)
        value = np.einsum("mi,mi->m", weights, corner)
        value[outside] = self.heights[self._tree.query(uv[outside])[1]]
        transform = mesh.transform[np.maximum(simplex, 0), :2]          # rows: d(weight_i)/d(uv), i = 0, 1
        slope = np.einsum("mij,mi->mj", transform, corner[:, :2] - corner[:, 2:])
        slope[outside] = 0.0
        return value, slope

    def __call__(self, uv) -> np.ndarray:
        """(m,) h at (m, 2) points."""
        return self.value_and_gradient(uv)[0]

    def gradient(self, uv) -> np.ndarray:
        """(m, 2) grad h at (m, 2) points (each triangle's; 0 beyond the ring)."""
        return self.value_and_gradient(uv)[1]


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


def annulus_points(points, labels, slices, planes, axis, stack, floor: float):
    """(k, 3) the points the base passes over, and (k,) how far above each it passes (mm): every valve point
    (:data:`ABOVE_VALVES`), and each end of a wall contour on a slice out of the short-axis ``stack`` (a long-axis
    slice, whatever its labels' prefix) that lies higher than ``floor`` along ``axis`` (:data:`ABOVE_ANNULUS`; its
    other end is at the apex; a closed contour has no end).  A contour's ends are those of the longest paths of its
    points in its slice (:func:`~bitemesh.core.sources.contours.slices.polylines`); ``floor`` is the basal short-axis
    slice's height, the other end of such a contour being at the apex."""
    chosen = [points[np.isin(labels, BIVME_VALVES)]]
    wall = np.isin(labels, [label for members in BIVME_SURFACES.values() for label in members])
    for label in np.unique(labels[wall]).tolist():
        for number in np.unique(slices[(labels == label) & (slices >= 0)]).tolist():
            members = np.flatnonzero((labels == label) & (slices == number))
            if number in stack or number not in planes or len(members) < 3:
                continue
            q = planes[number].project(points[members])
            paths, _, spacing = polylines(q, GAP_FACTOR)
            for path in paths:
                if len(path) > 3 and not is_closed(q, path, spacing, GAP_FACTOR):
                    ends = points[members[[path[0], path[-1]]]]
                    chosen.append(ends[ends @ axis > floor])
    lift = np.full(sum(map(len, chosen)), ABOVE_ANNULUS)
    lift[:len(chosen[0])] = ABOVE_VALVES
    return np.vstack(chosen), lift


def annulus_surface(points, labels, slices, planes):
    """The base of biv-me contours (see the module docstring), and a note; None (and a note) without valve points
    and long-axis contour ends, or without a short-axis stack to measure heights along."""
    axis, numbers, heights = short_axis_stack(points, labels, slices, planes)
    if axis is None:
        return None, ()
    basal = int(np.argmax(heights))
    anchors, lift = annulus_points(points, labels, slices, planes, axis, numbers, heights[basal])
    if len(anchors) < 3:
        return BaseSurface.plane(planes[numbers[basal]].centre, axis), (
            f"no valve points or long-axis contours above the basal short-axis slice: the base is that slice's "
            f"plane (slice {numbers[basal]})",)
    base = BaseSurface.plane(anchors.mean(axis=0), axis)
    covered = [label for members in BIVME_SURFACES.values() for label in members] + list(BIVME_VALVES)
    wall = points[np.isin(labels, covered)]
    clearance = np.where(np.isin(labels[np.isin(labels, covered)], BIVME_VALVES), ABOVE_VALVES, ABOVE_ANNULUS)
    anchors = _highest_within(anchors + lift[:, None] * axis, base, ANCHOR_CELL)
    anchors = _with_anchors(anchors, _plateau(anchors, base), base)
    for round_ in range(ENVELOPE_ROUNDS + 1):
        in_plane = (anchors - base.point) @ base.axes.T
        spread = np.linalg.svd(in_plane - in_plane.mean(axis=0), compute_uv=False)
        if spread[1] <= 0.05 * spread[0]:   # on one line: only the plane through them, perpendicular to the stack
            return base, ()
        surface = replace(base, heights=PiecewiseLinear.through(in_plane, (anchors - base.point) @ axis))
        short = surface.below(wall) < clearance - ENVELOPE_TOLERANCE
        if not short.any() or round_ == ENVELOPE_ROUNDS:
            return surface, ()
        slope = surface.heights.gradient((wall[short] - base.point) @ base.axes.T)
        lift = clearance[short] * np.minimum(np.sqrt(1.0 + np.einsum("ij,ij->i", slope, slope)), STEEPEST)
        added = _highest_within(wall[short] + lift[:, None] * axis, base, ANCHOR_MERGE)
        anchors = _with_anchors(anchors, np.vstack([added, _plateau(added, surface)]), base)


def _highest_within(anchors: np.ndarray, base: BaseSurface, radius: float) -> np.ndarray:
    """Of (k, 3) anchors, each that no higher one (along the base's normal) kept before it stands within ``radius``
    (mm) of in the base's plane: the base passes over all of them, and a lower anchor so near a higher one would
    only make it fall steeply between them (a long-axis contour's end 3 mm short of its mitral point, 2 mm below
    it, gave a cliff that left a roof of wall thinner than a cell over the point)."""
    offset = anchors - base.point
    order = np.argsort(-(offset @ base.normal), kind="stable")
    in_plane = offset[order] @ base.axes.T
    tree = cKDTree(in_plane)
    kept = np.zeros(len(anchors), bool)
    for rank, neighbours in enumerate(tree.query_ball_point(in_plane, radius)):
        kept[rank] = not kept[[n for n in neighbours if n < rank]].any()
    return anchors[order[kept]]


def _plateau(anchors: np.ndarray, surface: BaseSurface) -> np.ndarray:
    """(6 k, 3) anchors around each of (k, 3) anchors, :data:`PLATEAU` from it in the base's plane, at its height or
    the base's (``surface``) where that is higher: the base stays at least as high over the wall around the point
    as over the point.  (A long-axis contour that runs up the RV outflow tract projects to a short segment of the
    base's plane: through its highest point alone, the base fell in a cliff beside it, 0.25 mm from its lower points
    along the slope, and the RV free wall under it was lost, 11.8 mm from the mesh.)"""
    angle = np.linspace(0.0, 2.0 * np.pi, 6, endpoint=False)
    ring = PLATEAU * np.column_stack([np.cos(angle), np.sin(angle)]) @ surface.axes              # (6, 3)
    around = (anchors[:, None, :] + ring).reshape(-1, 3)
    if surface.heights is not None:
        offset = around - surface.point
        rise = np.maximum(surface.heights(offset @ surface.axes.T) - offset @ surface.normal, 0.0)
        around += rise[:, None] * surface.normal
    return around


def _with_anchors(anchors: np.ndarray, added: np.ndarray, base: BaseSurface) -> np.ndarray:
    """(k, 3) anchors and (a, 3) more that the base must pass through: each added one kept where it stands (the
    highest within :data:`ANCHOR_MERGE`), or, within :data:`ANCHOR_MERGE` of an anchor, raising that anchor to its
    height (a second anchor so near at another height would tilt the base steeply between them).  An added anchor is
    never dropped for a higher one of its :data:`ANCHOR_CELL` square: the base interpolated between that one and
    the next dipped to within 1 mm of a mitral point, leaving a wedge of wall thinner than a cell there."""
    added = _highest_within(added, base, ANCHOR_MERGE)
    distance, nearest = cKDTree((anchors - base.point) @ base.axes.T).query((added - base.point) @ base.axes.T)
    near = distance < ANCHOR_MERGE
    anchors = anchors.copy()
    rise = np.zeros(len(anchors))
    np.maximum.at(rise, nearest[near], (added[near] - anchors[nearest[near]]) @ base.normal)
    anchors += rise[:, None] * base.normal
    return np.vstack([anchors, added[~near]])


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
