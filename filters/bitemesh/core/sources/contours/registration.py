"""Breath-hold misregistration: each short-axis slice moved in its plane onto the long-axis contours.

Short-axis slices of a cine MR study come from separate breath-holds, so a slice can sit 2 to 5 mm off the others in
its plane; model builders (biv-me, CAP) correct this against the long-axis contours (Sinclair et al., MICCAI 2017:
each slice registered to where the other slices' contours cross its plane).  Here the long-axis slices stay fixed
and each short-axis slice gets the in-plane translation that best lays its contours of each surface through the
points where the long-axis contours of the same surface cross its plane: point-to-curve least squares (the
crossings to the nearest segment of the slice's polylines, each pair's residual along the segment's normal),
iterated to convergence, with Tukey's weights of scale :data:`OUTLIER` (a crossing of another part of the heart
does not pull), a crossing beyond the tip of an open arc pairing with nothing.

A shift is estimated only when the crossings pin both in-plane directions (the smallest eigenvalue of the normal
matrix is at least :data:`MIN_PIN` of the crossings' count): otherwise the slice stays where it is and the note says
so; a shift is never guessed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cardiac import short_axis_stack
from .slices import GAP_FACTOR, is_closed, polylines

#: a crossing farther than this (input units, mm) from the slice's contour is no pair (another part of the heart).
OUTLIER = 10.0
#: a slice whose contours stay this far (mm, median) from the crossings whatever the shift is left out: beyond any
#: breath-hold's shift (2 to 5 mm) and a basal slice's through-plane motion (up to about 12 mm at end-systole).
MISPLACED = 15.0
#: the normal matrix's smallest eigenvalue, per crossing, below which a direction is not pinned.
MIN_PIN = 0.05
#: at least this many crossings in all for a slice's shift.
MIN_CROSSINGS = 4
#: a shift smaller than this (mm, about the tracing noise of contours on 1.4 mm pixels) is no misregistration: the
#: slice stays where it is (and a synthetic heart's exact contours are not moved by the rounding of the fit).
SMALLEST = 0.5
#: contours that still disagree by more than this (mm, median, about a pixel) once registered are said to.
DISAGREEING = 1.5


def segment_ends(q: np.ndarray, gap_factor: float = GAP_FACTOR) -> np.ndarray:
    """(s, 2) int64: the point indices of the segments of the polylines through (m, 2) points (each path's
    consecutive points, a closed one's ends joined)."""
    paths, _, spacing = polylines(q, gap_factor)
    pieces = [np.zeros((0, 2), np.int64)]
    for path in paths:
        if len(path) < 2:
            continue
        ends = np.r_[path, path[:1]] if is_closed(q, path, spacing, gap_factor) else np.asarray(path)
        pieces.append(np.column_stack([ends[:-1], ends[1:]]))
    return np.concatenate(pieces)


def crossings(segments: np.ndarray, plane) -> np.ndarray:
    """(c, 3) the points where (s, 2, 3) segments cross ``plane`` (a SlicePlane)."""
    height = (segments - plane.centre) @ plane.normal
    crossing = (height[:, 0] < 0) != (height[:, 1] < 0)
    a, b = segments[crossing, 0], segments[crossing, 1]
    t = height[crossing, 0] / (height[crossing, 0] - height[crossing, 1])
    return a + t[:, None] * (b - a)


def _nearest_on_segments(points: np.ndarray, segments: np.ndarray, tips: np.ndarray | None = None):
    """For (c, 2) points, the nearest point on (s, 2, 2) segments, the unit normal of that segment and the
    distance; inf where the nearest point is an open contour's tip (``tips`` (s, 2) bool: which segment ends are a
    polyline's ends), so that a point beyond an arc's end pairs with nothing."""
    a, b = segments[:, 0], segments[:, 1]
    edge = b - a
    length = np.maximum(np.einsum("sk,sk->s", edge, edge), 1e-300)
    t = np.clip(np.einsum("csk,sk->cs", points[:, None] - a, edge) / length, 0.0, 1.0)
    nearest = a + t[..., None] * edge   # (c, s, 2)
    distance = np.linalg.norm(points[:, None] - nearest, axis=2)
    best = np.argmin(distance, axis=1)
    rows = np.arange(len(points))
    normal = np.column_stack([-edge[best, 1], edge[best, 0]]) / np.sqrt(length[best])[:, None]
    closest = distance[rows, best]
    if tips is not None:
        at = t[rows, best]
        closest = np.where((tips[best, 0] & (at <= 0.0)) | (tips[best, 1] & (at >= 1.0)), np.inf, closest)
    return nearest[rows, best], normal, closest


def _residuals(pairs, shift) -> np.ndarray:
    """The distance of every crossing, moved by -``shift``, to its slice's contour (those beside it)."""
    distances = np.concatenate([_nearest_on_segments(points - shift, segments, tips)[2]
                                for segments, tips, points in pairs if len(segments) and len(points)]
                               or [np.zeros(0)])
    return distances[np.isfinite(distances)]


def in_plane_shift(pairs, iterations: int = 100):
    """The 2D translation t of a slice's contours that lays them through the crossings: pairs is a list of
    ((s, 2, 2) segments of the slice's contour of a surface, (s, 2) which of their ends are a polyline's tips,
    (c, 2) crossings of that surface), all in the slice's coordinates; a crossing beyond an arc's tip pairs with
    nothing (an arc may slide along it).  Each step is a weighted least-squares one (Tukey's biweight of the
    residuals, scale :data:`OUTLIER`), so that crossings of another part of the heart do not pull.

    Returns
    -------
    t : (2,) or None when the crossings do not pin both directions; before, after : the median distance of the
    crossings to the contour without and with t
    """
    shift = np.zeros(2)
    before = _residuals(pairs, shift)
    if len(before) < MIN_CROSSINGS:
        return None, np.nan, np.nan   # too few to judge
    for _ in range(iterations):
        matrix, right, weight_sum = np.zeros((2, 2)), np.zeros(2), 0.0
        for segments, tips, points in pairs:
            if not len(segments) or not len(points):
                continue
            nearest, normal, distance = _nearest_on_segments(points - shift, segments, tips)
            weight = np.clip(1.0 - (distance / OUTLIER) ** 2, 0.0, None) ** 2
            residual = np.where(weight > 0, np.einsum("ck,ck->c", points - shift - nearest, normal), 0.0)
            matrix += (normal * weight[:, None]).T @ normal
            right += (normal * weight[:, None]).T @ residual
            weight_sum += float(weight.sum())
        if weight_sum < MIN_CROSSINGS or np.linalg.eigvalsh(matrix)[0] < MIN_PIN * weight_sum:
            return None, float(np.median(before)), np.nan
        step = np.linalg.solve(matrix, right)
        shift = shift + step
        if np.linalg.norm(step) < 1e-9:   # converged to rounding: the same shift whatever the platform
            break
    return shift, float(np.median(before)), float(np.median(_residuals(pairs, shift)))


@dataclass(frozen=True)
class Registration:
    """The short-axis slices against the long-axis contours.

    Attributes
    ----------
    shifts : slice id -> (3,) float64, the in-plane translation added to that slice's points (input units), those of
        at least :data:`SMALLEST`
    unpinned : the slice ids whose crossings do not pin a shift (left in place)
    outliers : slice id -> the median distance (input units) of the crossings to its contours, beyond
        :data:`MISPLACED` whatever the shift: contours no long-axis contour agrees with, left out
    disagreement : the median over the slices kept of that distance once moved (input units): how far the short-
        and long-axis contours still disagree, which no surface through both can undo
    """

    shifts: dict = field(default_factory=dict)
    unpinned: tuple = ()
    outliers: dict = field(default_factory=dict)
    disagreement: float = 0.0

    def notes(self) -> tuple:
        """What was moved, left in place and left out, one sentence each."""
        moved = self.shifts
        notes = ()
        if moved:
            notes += ("short-axis slices moved onto the long-axis contours (breath-hold misregistration): "
                      + ", ".join(f"slice {number} by {np.linalg.norm(shift):.1f} mm"
                                  for number, shift in moved.items()),)
        if self.unpinned:
            notes += (f"short-axis slice(s) {', '.join(map(str, self.unpinned))} left in place: too few long-axis "
                      "contours cross them to pin a shift",)
        if self.outliers:
            notes += ("short-axis slice(s) left out, their contours " + ", ".join(
                f"{distance:.0f} mm (slice {number})" for number, distance in self.outliers.items())
                + f" from where the long-axis contours cross them, more than {MISPLACED:g} mm whatever the shift: "
                "check those slices' positions (the image header) or their labels",)
        if self.disagreement > DISAGREEING:
            notes += (f"the short- and long-axis contours still disagree by {self.disagreement:.1f} mm (median) once "
                      "registered (motion through the slices, or views of other breath-holds): the surfaces pass "
                      "between them, and the fidelity bounds count that disagreement as the contours' noise",)
        return notes


def register_short_axis(points, labels, slices, planes, surfaces: dict,
                        gap_factor: float = GAP_FACTOR) -> Registration:
    """Each short-axis slice against the long-axis contours (see the module docstring).

    Parameters
    ----------
    points : (n, 3) float64; labels : (n,) str; slices : (n,) int; planes : slice id -> SlicePlane
    surfaces : surface name -> its labels (each surface's short-axis contours are registered to its long-axis ones)
    """
    axis, stack, _ = short_axis_stack(points, labels, slices, planes)
    if axis is None:
        return Registration()
    lines = {}   # (surface, long-axis slice) -> its contour's segments (s, 2, 3)
    for name, members in surfaces.items():
        for other in (number for number in planes if number not in stack):
            theirs = np.flatnonzero((slices == other) & np.isin(labels, members))
            if len(theirs) >= 3:
                lines[name, other] = points[theirs][segment_ends(planes[other].project(points[theirs]), gap_factor)]
    shifts, unpinned, outliers, residuals = {}, [], {}, []
    for number in stack:
        plane = planes[number]
        pairs = []
        for name, members in surfaces.items():
            mine = (slices == number) & np.isin(labels, members)
            cross = [crossings(segments, plane) for (surface, _), segments in lines.items() if surface == name]
            if mine.sum() < 3 or not cross:
                continue
            q = plane.project(points[mine])
            ends = segment_ends(q, gap_factor)
            tips = np.bincount(ends.ravel(), minlength=len(q))[ends] == 1
            pairs.append((q[ends], tips, plane.project(np.concatenate(cross))))
        if not pairs:
            continue
        shift, before, after = in_plane_shift(pairs)
        moved = shift is not None and np.linalg.norm(shift) >= SMALLEST
        if (after if shift is not None else before) > MISPLACED:
            outliers[number] = before if shift is None else after
            continue
        if shift is None:
            unpinned.append(number)
        elif moved:
            shifts[number] = shift @ plane.axes
        residuals.append(after if moved else before)
    residuals = [value for value in residuals if np.isfinite(value)]
    return Registration(shifts, tuple(unpinned), outliers, float(np.median(residuals)) if residuals else 0.0)
