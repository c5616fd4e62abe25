"""One implicit function per contour surface: the partition-of-unity RBF of :mod:`bitemesh.core.implicit.rbf` through
the contour points and their off-surface points.

The constraints: f = 0 on the contour points, +delta inside and -delta outside at p -/+ delta n (n the in-plane
outward normal, :func:`off_surface_offsets`), and optional interior points (a valve's centre inside its cavity, in
every patch).  No patch is narrower than the gap between the slices (each must see contours on several slices), and
the points are thinned first (:func:`thinned`).

Convention: f > 0 inside, about the signed distance (input units) near f = 0.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ...errors import InvalidInputError, check_choice, check_number, check_points
from ...parameters import LabelledParameters
from ...parameters import KERNELS
from ...implicit.rbf import RBFImplicit, fit_partition

#: the points are fitted thinned to this x the off-surface offset apart (contours traced on 1.4 mm pixels are about
#: 3 mm apart; a denser resampling adds time, not shape).
THIN_PER_OFFSET = 0.4
#: the largest distance (input units) of the off-surface constraints from the contours by default: 4 mm, about a
#: wall thickness of an adult heart (a smaller heart's is scaled in proportion by its frame).
OFFSET = 4.0
#: no patch of a surface's fit is narrower than this x the median distance between its slices.
PATCH_PER_GAP = 1.0


def off_surface_offsets(points, normals, offset) -> np.ndarray:
    """(n,) delta_i: ``offset``, halved (up to 5 times) until both p_i +/- delta_i n_i are nearer to p_i than to
    any other point (about: no other point within 0.75 delta_i of them); 0 where there is no normal.

    Along a contour the neighbours lie across the normal, so delta may exceed the point spacing; it shrinks where
    another wall of the same surface is near (the thin apical RV cavity).
    """
    has = np.isfinite(normals).all(axis=1)
    delta = np.where(has, float(offset), 0.0)
    tree = cKDTree(points)
    direction = np.where(has[:, None], normals, 0.0)
    for _ in range(5):
        crowded = np.zeros(len(points), bool)
        for sign in (-1.0, 1.0):
            crowded |= tree.query(points + sign * delta[:, None] * direction)[0] < 0.75 * delta - 1e-12
        if not crowded.any():
            break
        delta[crowded] *= 0.5
    return delta


def _constraints(points, normals, offset, interior):
    """(m, 3) constraint points and (m,) their values: the points (0), the off-surface points (+/- delta) that
    contradict no other constraint, and the interior points."""
    delta = off_surface_offsets(points, normals, offset)
    has = delta > 0
    direction = np.where(has[:, None], normals, 0.0)
    off = np.vstack([points - delta[:, None] * direction, points + delta[:, None] * direction])[np.r_[has, has]]
    off_values = np.r_[delta, -delta][np.r_[has, has]]
    # An off-surface point closer than delta / 2 to another centre contradicts it (contours that cross or hook
    # into each other): leave it out.
    clear = cKDTree(np.vstack([points, off])).query(off, k=2)[0][:, 1] >= 0.5 * np.abs(off_values)
    centres, values = np.vstack([points, off[clear]]), np.r_[np.zeros(len(points)), off_values[clear]]
    if interior is not None:
        extra, extra_values = check_points(interior[0], "interior points", dims=(3,)), np.asarray(interior[1], float)
        if extra_values.shape != (len(extra),) or not np.isfinite(extra_values).all():
            raise InvalidInputError(f"interior values must be {len(extra)} finite numbers, got {interior[1]!r}")
        centres, values = np.vstack([centres, extra]), np.r_[values, extra_values]
    return centres, values


def thinned(points: np.ndarray, spacing: float) -> np.ndarray:
    """Indices (ascending) of a subset of (n, 3) points no two of which are closer than ``spacing``, greedily in
    their order: contours resampled more densely than their slices are apart say nothing more about the surface
    between the slices, and would only cost time."""
    keep, dropped = [], np.zeros(len(points), bool)
    for index, near in enumerate(cKDTree(points).query_ball_point(points, spacing)):
        if not dropped[index]:
            keep.append(index)
            dropped[near] = True
    return np.array(keep, dtype=np.int64)


def fit_contour_rbf(points, normals, *, kernel: str = LabelledParameters.kernel,
                    offset: float = OFFSET, smoothing: float = LabelledParameters.smoothing,
                    interior=None, min_patch: float = 0.0, min_spacing=None, near=None) -> RBFImplicit:
    """The implicit of contour points with (in-plane) outward normals: RBFs on patches blended by a partition of
    unity (:func:`bitemesh.core.implicit.rbf.fit_partition`).

    f is 0 on the points and +delta_i (inside) / -delta_i (outside) at p_i -/+ delta_i n_i, with delta_i from
    :func:`off_surface_offsets` (``offset``, halved where another point is near), so that no off-surface point passes
    another sample; an off-surface point closer than delta_i / 2 to another centre (contours that cross or hook
    into each other) is left out.  Points without a normal (NaN) constrain only f = 0.  A nearly singular system
    (points repeated within rounding) is refused.

    Parameters
    ----------
    points : (n, 3) float64, input units, distinct
    normals : (n, 3) float64 outward unit normals, NaN rows allowed
    kernel : "linear" (phi = r, Carr's biharmonic, the default), "cubic" (r^3) or "thin_plate" (r^2 log r)
    offset : float, input units, the largest off-surface distance
    smoothing : float >= 0, added to the diagonal of each kernel matrix (0 interpolates), in units of
        phi(patch diameter)
    interior : ((k, 3), (k,)) float64, optional: more points and their values (> 0 inside, about the distance to
        the surface), e.g. the centre of a valve through which a cavity must open
    min_patch : float, input units: no patch's radius is below this (the gap between the slices, so that each
        patch sees contours on several slices); 0 splits by the number of constraints alone
    min_spacing : float, input units: the points are fitted :func:`thinned` to this spacing; default
        :data:`THIN_PER_OFFSET` x offset
    near : (q, 3) float64, optional: the function will be evaluated at these points only (see
        :func:`~bitemesh.core.implicit.rbf.fit_partition`)

    Returns
    -------
    RBFImplicit (without a box: not clamped)
    """
    points = check_points(points, dims=(3,))
    kernel = check_choice(kernel, "kernel", KERNELS)
    offset = check_number(offset, "offset", low=0, low_open=True)
    smoothing = check_number(smoothing, "smoothing", low=0)
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != points.shape:
        raise InvalidInputError(f"normals must have the shape of points {points.shape}, got {normals.shape}")
    kept = thinned(points, THIN_PER_OFFSET * offset if min_spacing is None
                   else check_number(min_spacing, "min_spacing", low=0))
    points, normals = points[kept], normals[kept]
    constraints, values = _constraints(points, normals, offset, interior)
    shift, scale = points.mean(axis=0), float(np.linalg.norm(np.ptp(points, axis=0)))
    return fit_partition(constraints, values, kernel=kernel, smoothing=smoothing,
                         min_patch=check_number(min_patch, "min_patch", low=0),
                         shared=0 if interior is None else len(interior[0]), frame=(shift, scale),
                         near=near, what=f"{len(points)} contour points")
