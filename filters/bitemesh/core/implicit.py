"""Scattered points -> implicit function f, section 4.1 of the paper.

Convention (the contract of :mod:`bitemesh.core.grid`): f > 0 inside, f < 0 outside, approximately the signed
distance in input units near f = 0.  Normals point outward.

Dense 3D samples use the Multilevel Partition of Unity of Ohtake, Belyaev, Alexa, Turk and Seidel (SIGGRAPH 2003;
:mod:`bitemesh.core.mpu`); sparse samples (2D contours) a thin-plate radial basis function.  Missing normals are
estimated as in Hoppe et al. (SIGGRAPH 1992; :mod:`bitemesh.core.normals`).  Both reconstructions are clamped by
the depth in the data's bounding box, so that every point far from the data is outside.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.spatial import cKDTree

from .errors import InvalidInputError, check_choice, check_number, check_points
from .grid import bounding_box, box_depth
from .mpu import MIN_POINTS, MPUImplicit, fit_mpu  # noqa: F401 (MPUImplicit: imported from here as before)
from .normals import check_normals, check_spans_space, estimate_normals, unit_normals
from .progress import ProgressCallback, report, sub_progress

#: most points fit_rbf accepts: it solves a dense system with 3 n unknowns.
MAX_RBF_POINTS = 2000


# --- thin-plate RBF for sparse data --------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class RBFImplicit:
    """A thin-plate RBF interpolant of on- and off-surface values, clamped by the bounding-box depth.

    Attributes
    ----------
    interpolant : scipy.interpolate.RBFInterpolator, (m, k) points -> (m,) values, > 0 inside
    lower, upper : (k,) float64, the data's bounding box; f <= depth in it
    """

    interpolant: RBFInterpolator
    lower: np.ndarray
    upper: np.ndarray

    def __call__(self, x) -> np.ndarray:
        """(m,) f at (m, k) points x."""
        x = check_points(x, "x", dims=(len(self.lower),))
        return np.minimum(self.interpolant(x), box_depth(x, self.lower, self.upper))


def fit_rbf(points, normals, *, offset=None, smoothing: float = 0.0) -> RBFImplicit:
    """Thin-plate RBF implicit of sparse oriented points (Carr et al. 2001), k = 2 or 3.

    The interpolant is 0 on the points and +delta_i / -delta_i at p_i -/+ delta_i n_i (inside / outside), with
    delta_i = min(offset, half the distance from p_i to its nearest neighbour), so off-surface points never pass
    another sample.

    Parameters
    ----------
    points : (n, k) float64, input units, distinct, n <= 2000
    normals : (n, k) float64, outward
    offset : float, input units; default 1 % of the bounding-box diagonal
    smoothing : float, RBFInterpolator smoothing (0 interpolates)

    Returns
    -------
    RBFImplicit, callable (m, k) -> (m,), f > 0 inside
    """
    points = check_points(points)
    if len(points) > MAX_RBF_POINTS:
        raise InvalidInputError(
            f"method 'rbf' accepts at most {MAX_RBF_POINTS} points (its dense system grows as n^2), got "
            f"{len(points)}; use method='mpu' (3D) or thin the points")
    normals = unit_normals(normals, points.shape)
    lower, upper, diagonal = bounding_box(points)
    offset = 0.01 * diagonal if offset is None else check_number(offset, "offset", low=0, low_open=True)
    smoothing = check_number(smoothing, "smoothing", low=0)
    spacing, _ = cKDTree(points).query(points, k=2)
    if not (spacing[:, 1] > 0).all():
        raise InvalidInputError("points contains duplicate points; remove them (points_to_implicit does)")
    delta = np.minimum(offset, 0.5 * spacing[:, 1])[:, None]
    interpolant = RBFInterpolator(np.vstack([points, points - delta * normals, points + delta * normals]),
                                  np.r_[np.zeros(len(points)), delta[:, 0], -delta[:, 0]],
                                  kernel="thin_plate_spline", smoothing=smoothing)
    return RBFImplicit(interpolant, lower, upper)


# --- the step ------------------------------------------------------------------------------------------------------

def _prepared(points, normals, method: str):
    """Checked points without exact duplicates (first kept) and their checked normals (or None)."""
    points = check_points(points)
    method = check_choice(method, "method", ("mpu", "rbf"))
    if method == "mpu" and points.shape[1] != 3:
        raise InvalidInputError(
            f"method 'mpu' needs 3D points, got {points.shape[1]}D points; use method='rbf' for 2D contours")
    if normals is not None:
        normals = check_normals(points, normals)
    _, first = np.unique(points, axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) < MIN_POINTS:
        raise InvalidInputError(f"points: need at least {MIN_POINTS} distinct points, got {len(keep)}")
    check_spans_space(points[keep])
    return points[keep], None if normals is None else normals[keep]


def _fit(points, normals, method: str, error_bound, progress: ProgressCallback):
    """Estimate missing normals, then fit f by ``method`` to prepared points."""
    if normals is None:
        report(progress, 0.0, "estimating normals")
        normals = estimate_normals(points, neighbours=min(12, len(points) - 1))
    report(progress, 0.25, f"fitting {method.upper()}")
    if method == "mpu":
        return fit_mpu(points, normals, error_bound=error_bound, progress=sub_progress(progress, 0.25, 1.0))
    function = fit_rbf(points, normals)
    report(progress, 1.0, "fitting RBF: done")
    return function


def fit_implicit(points, normals=None, *, method: str = "mpu", error_bound=None,
                 progress: ProgressCallback = None):
    """Reconstruct f from scattered points, as a function (points_to_implicit samples it on a grid).

    Parameters
    ----------
    points : (n, k) float64, input units, k = 3 for "mpu", 2 or 3 for "rbf", n >= 10; exact duplicates are dropped
    normals : (n, k) float64, outward, optional (estimated when omitted; checked with check_normals when given)
    method : "mpu" (dense 3D samples) or "rbf" (sparse samples, at most 2000 points)
    error_bound : float, input units, MPU fit tolerance; default 0.005 x bounding-box diagonal (ignored by "rbf")
    progress : callable(fraction, message), optional

    Returns
    -------
    MPUImplicit or RBFImplicit: callable (m, k) points -> (m,) f, f > 0 inside
    """
    points, normals = _prepared(points, normals, method)
    return _fit(points, normals, method, error_bound, progress)


def __getattr__(name):
    """``points_to_implicit`` lives in :mod:`bitemesh.core.pipeline` (it drops outliers and centres the points
    first); imported from here as before."""
    if name == "points_to_implicit":
        from .pipeline import points_to_implicit
        return points_to_implicit
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
