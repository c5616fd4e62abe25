"""Breath-hold misregistration: every slice moved in its plane so that the contours meet where the slices cross.

Each slice of a cine MR study comes from its own breath-hold, so a slice can sit 2 to 5 mm off the others in its
plane, the long-axis views as well as the short-axis ones; model builders correct this where the slices cross
(Sinclair et al., MICCAI 2017; biv-me moves both the short- and the long-axis slices).  Here every slice's in-plane
translation is found at once: where a slice's contour of a surface crosses another slice's plane, that crossing
should lie on the other slice's contour of the same surface.  The translations minimise the crossings' distances
to those contours (point to curve, along the contour's normal; Tukey's biweight of scale :data:`OUTLIER`, so that a
crossing of another part of the heart does not pull, and a crossing beyond an open arc's tip pairs with nothing)
plus a weight x the squared translations (:data:`PRIOR`: no slice moves without a reason and the heart as a whole
does not drift), by Gauss-Newton steps halved until the cost falls.  No slice is fixed: the long-axis views hold
the heart's place more firmly than the short-axis slices, and one that disagrees with all of them moves too.

A slice moves only when the crossings pin both of its in-plane directions (the smallest eigenvalue of its normal
matrix is at least :data:`MIN_PIN` of its crossings' count): otherwise it stays where it is and the note says so; a
shift is never guessed.  A slice whose contours stay far from the crossings whatever the shift (farther than
:data:`MISPLACED` x the other slices' disagreement, and than :data:`FAR`), or would meet them only beyond
:data:`MAX_SHIFT`, is left out and named.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cardiac import short_axis_stack
from .slices import GAP_FACTOR, is_closed, polylines, slice_planes

#: a crossing farther than this (input units, mm) from the slice's contour is no pair (another part of the heart).
OUTLIER = 10.0
#: the weights of a slice's squared translation against the crossings' squared distances: a slice off the
#: short-axis stack (a long-axis view) moves 1 mm only for what 10 crossings gain by it, a slice of the stack for what
#: a tenth of one does.  The few long-axis views thus hold the heart's place while each short-axis slice takes the
#: shift its crossings give it, and a long-axis view that disagrees with all the short-axis slices still moves.
#: Measured on biv-me patient1 (frames 0 and 7): the same weight for every slice lets the slices drift together by
#: about 2 mm (surfaces 1.6 mm from biv-me's, against 1.06-1.26 with the long-axis slices fixed); these weights give
#: 1.02 and 1.21 mm, and short-axis slices shifted by 2-5 mm are found within 1 mm.
PRIOR, STACK_PRIOR = 10.0, 0.1
#: a slice that would have to move farther than this (mm) is left out: no breath-hold moves a heart that far in
#: the slice's plane (2 to 5 mm in cine MR), the match is another part of the heart.
MAX_SHIFT = 10.0
#: slices whose planes are within this angle (degrees) of each other do not cross (a short-axis stack).
PARALLEL = 10.0
#: a contour segment at less than asin(GRAZING) to a plane crosses it at no well-defined point.
GRAZING = 0.2
#: the normal matrix's smallest eigenvalue, per crossing, below which a direction is not pinned.
MIN_PIN = 0.05
#: at least this many crossings (by weight) on a slice for its shift.
MIN_CROSSINGS = 4
#: a slice whose contours stay more than this x the median of the slices' distances (mm, median) from the crossings,
#: and more than :data:`FAR`, whatever the shift, is left out: the others agree and it does not.  Not the basal or
#: apical short-axis slice: there the heart's section changes fastest along the axis, so that a breath-hold's shift
#: through the slices, which no in-plane shift undoes, leaves its contours 10-20 mm from the long-axis views' (biv-me
#: patient1's basal slice at end-systole), and a partial contour there is normal.
MISPLACED = 3.0
#: mm: a slice is never left out nearer than this (biv-me patient1's slices stay within 3.2 mm over its 25 frames,
#: the basal slice aside; a tilted slice of another export that the fit cannot follow, 7 mm).
FAR = 6.0
#: a shift smaller than this (mm, about the tracing noise of contours on 1.4 mm pixels) is no misregistration: the
#: slice stays where it is (and a synthetic heart's exact contours are not moved by the rounding of the fit).
SMALLEST = 0.5
#: contours that still disagree by more than this (mm, median) once registered are said to.
DISAGREEING = 1.5
#: Gauss-Newton steps at most, and halvings of a step.
ITERATIONS, HALVINGS = 50, 8


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


def _nearest_on_segments(points: np.ndarray, segments: np.ndarray, tips: np.ndarray):
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
    at = t[rows, best]
    closest = np.where((tips[best, 0] & (at <= 0.0)) | (tips[best, 1] & (at >= 1.0)), np.inf, distance[rows, best])
    return nearest[rows, best], normal, closest


def _contours(points, labels, slices, planes, surfaces: dict, gap_factor: float) -> dict:
    """(slice id, surface name) -> (its points (m, 3), in its plane (m, 2), segments' ends (s, 2), which ends are
    tips (s, 2) bool)."""
    contours = {}
    for number in sorted(planes):
        for name, members in surfaces.items():
            mine = points[(slices == number) & np.isin(labels, members)]
            if len(mine) < 3:
                continue
            flat = planes[number].project(mine)
            ends = segment_ends(flat, gap_factor)
            if len(ends):
                contours[number, name] = (mine, flat, ends, np.bincount(ends.ravel(), minlength=len(mine))[ends] == 1)
    return contours


def _crossing_pairs(planes, contours: dict) -> list:
    """The (crossed, crossing) keys of ``contours`` of one surface on slices that are not parallel."""
    parallel = np.cos(np.radians(PARALLEL))
    return [(key, other) for key in contours for other in contours
            if other[1] == key[1] and other[0] != key[0]
            and abs(planes[key[0]].normal @ planes[other[0]].normal) <= parallel]


def _crossing_terms(planes, contours: dict, pairs: list, shifts: dict) -> list:
    """Every crossing of a contour with another slice's plane, against that slice's contour of the same surface
    (``pairs`` of :func:`_crossing_pairs`), with the slices moved by ``shifts`` (slice id -> (2,) in-plane
    translation): a list of (i, j, residual (c,) along i's contour normal, distance (c,) to it (inf beyond a tip),
    d residual / d u_i (c, 2), d residual / d u_j (c, 2)), i the slice crossed and j the slice whose contour
    crosses it."""
    terms = []
    for (i, name), (j, _) in pairs:
        plane, (_, flat, ends, tips), (theirs, _, their_ends, _) = planes[i], contours[i, name], contours[j, name]
        crossing = (theirs + shifts[j] @ planes[j].axes)[their_ends]   # (s, 2, 3)
        height = (crossing - plane.centre) @ plane.normal
        a, along = crossing[:, 0], crossing[:, 1] - crossing[:, 0]
        rise = along @ plane.normal
        steep = ((height[:, 0] < 0) != (height[:, 1] < 0)) & (np.abs(rise) > GRAZING * np.linalg.norm(along, axis=1))
        if not steep.any():
            continue
        a, along, rise, height = a[steep], along[steep], rise[steep], height[steep]
        at = plane.project(a - (height[:, 0] / rise)[:, None] * along)
        nearest, normal, distance = _nearest_on_segments(at, (flat + shifts[i])[ends], tips)
        residual = np.einsum("ck,ck->c", at - nearest, normal)
        # moving slice j by t (in its plane) moves the crossing by (I - along n^T / rise) t
        moved = np.eye(3)[None] - along[:, :, None] * plane.normal[None, None, :] / rise[:, None, None]
        terms.append((i, j, residual, distance, -normal,
                      np.einsum("ck,kl,clm,nm->cn", normal, plane.axes, moved, planes[j].axes)))
    return terms


def _tukey(residual: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Tukey's biweight loss of each crossing (a crossing beyond a tip costs as much as one beyond OUTLIER)."""
    r = np.where(np.isfinite(distance), np.minimum(np.abs(residual), OUTLIER), OUTLIER)
    return OUTLIER ** 2 / 6.0 * (1.0 - (1.0 - (r / OUTLIER) ** 2) ** 3)


def _cost(terms: list, shifts: dict, prior: dict) -> float:
    return (sum(float(_tukey(residual, distance).sum()) for _, _, residual, distance, _, _ in terms)
            + sum(prior[number] * float(shift @ shift) for number, shift in shifts.items()))


def _solve(planes, contours: dict, prior: dict):
    """The in-plane translations of the slices of ``contours`` (module docstring): slice id -> (2,), the slices
    whose crossings do not pin them (kept at 0), and the final crossing terms."""
    numbers = sorted({number for number, _ in contours})
    index = {number: 2 * k for k, number in enumerate(numbers)}
    shifts = {number: np.zeros(2) for number in numbers}
    fixed: set = set()
    pairs = _crossing_pairs(planes, contours)
    terms = _crossing_terms(planes, contours, pairs, shifts)
    cost = _cost(terms, shifts, prior)
    for _ in range(ITERATIONS):
        held = np.repeat([prior[number] for number in numbers], 2)
        matrix, gradient = np.diag(held), np.zeros(2 * len(numbers))
        own = {number: np.zeros((2, 2)) for number in numbers}
        weights = dict.fromkeys(numbers, 0.0)
        for i, j, residual, distance, d_i, d_j in terms:
            weight = np.where(np.isfinite(distance), np.clip(1.0 - (residual / OUTLIER) ** 2, 0.0, None) ** 2, 0.0)
            for a, d_a in ((index[i], d_i), (index[j], d_j)):
                gradient[a:a + 2] += d_a.T @ (weight * residual)
                for b, d_b in ((index[i], d_i), (index[j], d_j)):
                    matrix[a:a + 2, b:b + 2] += (d_a * weight[:, None]).T @ d_b
            own[i] += (d_i * weight[:, None]).T @ d_i
            weights[i] += float(weight.sum())
        fixed |= {number for number in numbers
                  if weights[number] < MIN_CROSSINGS or np.linalg.eigvalsh(own[number])[0] < MIN_PIN * weights[number]}
        gradient += held * np.concatenate([shifts[number] for number in numbers])
        for number in fixed:   # held where it is
            a = index[number]
            matrix[a:a + 2], matrix[:, a:a + 2], gradient[a:a + 2] = 0.0, 0.0, shifts[number]
            matrix[a:a + 2, a:a + 2] = np.eye(2)
        step = -np.linalg.solve(matrix, gradient)
        for _ in range(HALVINGS):
            trial = {number: shifts[number] + step[index[number]:index[number] + 2] for number in numbers}
            trial_terms = _crossing_terms(planes, contours, pairs, trial)
            trial_cost = _cost(trial_terms, trial, prior)
            if trial_cost <= cost:
                break
            step = step / 2
        else:
            break   # no step lowers the cost: converged (to a kink of the nearest-segment pairing)
        shifts, terms, cost = trial, trial_terms, trial_cost
        if np.abs(step).max() < 1e-6:
            break
    return shifts, fixed, terms


def _distances(terms: list) -> dict:
    """Slice id -> the median distance (mm) of the crossings on it to its contours (those beside one)."""
    found: dict = {}
    for i, _, _, distance, _, _ in terms:
        found.setdefault(i, []).append(distance[np.isfinite(distance)])
    found = {number: np.concatenate(parts) for number, parts in found.items()}
    return {number: float(np.median(values)) for number, values in found.items() if len(values)}


@dataclass(frozen=True)
class Registration:
    """The slices against each other.

    Attributes
    ----------
    shifts : slice id -> (3,) float64, the in-plane translation added to that slice's points (input units), those of
        at least :data:`SMALLEST`
    unpinned : the slice ids whose crossings do not pin a shift (left in place)
    outliers : slice id -> how far (input units) its contours are from the crossings: their median distance whatever
        the shift, or the shift that would lay them there, beyond what the other slices show (:data:`MISPLACED`,
        :data:`FAR`, :data:`MAX_SHIFT`): contours no other slice agrees with, left out
    disagreement : the median over the slices kept of that distance once moved (input units): how far the contours
        still disagree where the slices cross, which no surface through all of them can undo
    contradicted : (slice id, surface name) -> how many crossings lie beside that contour (not beyond a tip) farther
        from it than a slice is left out by (:data:`MISPLACED`, :data:`FAR`), for the short-axis contours of slices
        kept that have any: where the other slices contradict them; which of their points stay is decided by
        :mod:`~bitemesh.core.sources.contours.contradicted`
    """

    shifts: dict = field(default_factory=dict)
    unpinned: tuple = ()
    outliers: dict = field(default_factory=dict)
    disagreement: float = 0.0
    contradicted: dict = field(default_factory=dict)

    def notes(self, scale: float = 1.0) -> tuple:
        """What was moved, left in place and left out, one sentence each; lengths times ``scale`` (the input's mm
        per unit of the registered points)."""
        notes = ()
        if self.shifts:
            notes += ("slices moved in their planes so that their contours meet where the slices cross (breath-hold "
                      "misregistration): " + ", ".join(f"slice {number} by {scale * np.linalg.norm(shift):.1f} mm"
                                                      for number, shift in self.shifts.items())
                      + "; the mesh and its fidelity figures follow the slices as moved (slice_shifts none: as "
                      "given)",)
        if self.unpinned:
            notes += (f"slice(s) {', '.join(map(str, self.unpinned))} left in place: too few other slices' contours "
                      "cross them to pin a shift",)
        if self.outliers:
            notes += ("slice(s) left out, their contours " + ", ".join(
                f"{scale * distance:.0f} mm (slice {number})" for number, distance in self.outliers.items())
                + " from where the other slices' contours cross them (whatever the shift, or by the shift needed), "
                f"while the others agree to {scale * self.disagreement:.1f} mm: check those slices' positions (the "
                "image header) or their labels",)
        if self.disagreement > DISAGREEING:
            notes += (f"the contours still disagree by {scale * self.disagreement:.1f} mm (median) where the slices "
                      "cross once registered (motion through the slices, or views of other breath-holds): the "
                      "surfaces pass between them, and the fidelity bounds count that disagreement as the contours' "
                      "noise",)
        return notes


def register_slices(points, labels, slices, planes, surfaces: dict, gap_factor: float = GAP_FACTOR) -> Registration:
    """Every slice against the others (see the module docstring); slices that do not cross another stay as given.

    Parameters
    ----------
    points : (n, 3) float64; labels : (n,) str; slices : (n,) int; planes : slice id -> SlicePlane
    surfaces : surface name -> its labels (each surface's contours are registered to those of the same surface)
    """
    contours = _contours(points, labels, slices, planes, surfaces, gap_factor)
    _, stack, heights = short_axis_stack(points, labels, slices, planes)
    prior = {number: STACK_PRIOR if number in (stack or ()) else PRIOR for number in planes}
    ends = {stack[int(np.argmin(heights))], stack[int(np.argmax(heights))]} if stack else set()
    outliers: dict = {}
    while True:
        if not contours:
            return Registration(outliers=outliers)
        shifts, fixed, terms = _solve(planes, contours, prior)
        if not terms:   # no two slices cross: nothing to register against
            return Registration(outliers=outliers)
        distances = _distances(terms)
        typical = float(np.median(list(distances.values()))) if distances else 0.0
        needed = {number: float(np.linalg.norm(shifts[number])) for number in distances}
        far = {number: max(distance, needed[number]) for number, distance in distances.items()
               if needed[number] > MAX_SHIFT or (distance > max(MISPLACED * typical, FAR) and number not in ends)}
        if not far:
            break
        outliers.update(far)   # then again without them: they may have pulled the others
        contours = {key: value for key, value in contours.items() if key[0] not in far}
    applied = {number: shift if number not in fixed and np.linalg.norm(shift) >= SMALLEST else np.zeros(2)
               for number, shift in shifts.items()}
    moved = {number: shift @ planes[number].axes for number, shift in applied.items() if shift.any()}
    contradicted = _contradicted(planes, contours, applied, max(MISPLACED * typical, FAR), set(stack or ()))
    return Registration(moved, tuple(sorted(fixed)), outliers, typical, contradicted)


def _contradicted(planes, contours: dict, shifts: dict, bound: float, stack: set) -> dict:
    """(slice id, surface name) -> how many crossings lie beside that contour farther than ``bound``, for the
    contours (of :func:`_contours`, the slices moved by ``shifts``) on the slices of the short-axis ``stack`` that
    have any (the long-axis views see the base and hold the heart's place)."""
    found: dict = {}
    for pair in _crossing_pairs(planes, contours):
        if pair[0][0] not in stack:
            continue
        for _, _, _, distance, _, _ in _crossing_terms(planes, contours, [pair], shifts):
            beyond = int((distance[np.isfinite(distance)] > bound).sum())
            if beyond:
                found[pair[0]] = found.get(pair[0], 0) + beyond
    return found


def registered(points, labels, slices, surfaces: dict, gap_factor: float = GAP_FACTOR):
    """The points with every slice moved as :func:`register_slices` finds and its outliers left out: (points,
    labels, slices) of the slices kept, and the Registration (the arguments as register_slices takes them, without
    the planes)."""
    registration = register_slices(points, labels, slices, slice_planes(points, slices), surfaces, gap_factor)
    if registration.shifts:
        points = points.copy()
        for number, shift in registration.shifts.items():
            points[slices == number] += shift
    kept = ~np.isin(slices, list(registration.outliers))
    return points[kept], labels[kept], slices[kept], registration
