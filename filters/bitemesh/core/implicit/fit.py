"""Scattered points -> implicit function f, section 4.1 of the paper.

Convention (the contract of :mod:`bitemesh.core.grid.sampled`): f > 0 inside, f < 0 outside, approximately the signed
distance in input units near f = 0.  Normals point outward.

Dense 3D samples use the Multilevel Partition of Unity of Ohtake, Belyaev, Alexa, Turk and Seidel (SIGGRAPH 2003;
:mod:`bitemesh.core.implicit.mpu`); sparse samples (2D or 3D contours, sparse points) polyharmonic radial basis
functions on patches blended by a partition of unity (:mod:`bitemesh.core.implicit.rbf`, the labelled contours' too).
Missing normals are estimated as in Hoppe et al. (SIGGRAPH 1992; :mod:`bitemesh.core.implicit.normals`).  Both
reconstructions are clamped by the depth in the data's bounding box, so that every point far from the data is outside.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError, check_choice, check_points
from .mpu import MIN_POINTS, fit_mpu
from .normals import check_normals, check_spans_space, estimate_normals
from ..progress import ProgressCallback, report, sub_progress
from .rbf import fit_rbf


# --- the step ------------------------------------------------------------------------------------------------------

def _prepared(points, normals, method: str):
    """Checked points without exact duplicates (first kept), their checked normals (or None), the method chosen."""
    points = check_points(points)
    method = check_choice(method, "method", ("auto", "mpu", "rbf"))
    if method == "mpu" and points.shape[1] != 3:
        raise InvalidInputError(
            f"method 'mpu' needs 3D points, got {points.shape[1]}D points; use method 'rbf' (--method rbf), which "
            "fits points in 2 to 5 dimensions")
    if normals is not None:
        normals = check_normals(points, normals)
    _, first = np.unique(points, axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) < MIN_POINTS:
        raise InvalidInputError(f"points: need at least {MIN_POINTS} distinct points, got {len(keep)}")
    check_spans_space(points[keep])
    return points[keep], None if normals is None else normals[keep], chosen_method(method, points.shape[1])


def chosen_method(method: str, dim: int) -> str:
    """``method`` as given, or for "auto" the one for ``dim``-D points: "mpu" in 3D, "rbf" in 2D."""
    return method if method != "auto" else "mpu" if dim == 3 else "rbf"


def _fit(points, normals, method: str, error_bound, progress: ProgressCallback):
    """Estimate missing normals, then fit f by ``method`` to prepared points."""
    if normals is None:
        report(progress, 0.0, "estimating normals")
        normals = estimate_normals(points, neighbours=min(12, len(points) - 1))
    report(progress, 0.25, f"fitting {method.upper()}")
    if method == "mpu":
        return fit_mpu(points, normals, error_bound=error_bound, progress=sub_progress(progress, 0.25, 1.0))
    return fit_rbf(points, normals, progress=sub_progress(progress, 0.25, 1.0))


def fit_implicit(points, normals=None, *, method: str = "auto", error_bound=None,
                 progress: ProgressCallback = None):
    """Reconstruct f from scattered points, as a function (points_to_implicit samples it on a grid).

    Parameters
    ----------
    points : (n, k) float64, input units, k = 3 for "mpu", 2 or 3 for "rbf", n >= 10; exact duplicates are dropped
    normals : (n, k) float64, outward, optional (estimated when omitted; checked with check_normals when given)
    method : "mpu" (dense 3D samples), "rbf" (sparse samples, 2D or 3D, at most MAX_RBF_POINTS) or "auto" (mpu
        in 3D, rbf in 2D)
    error_bound : float, input units, MPU fit tolerance; default 0.005 x bounding-box diagonal (ignored by "rbf")
    progress : callable(fraction, message), optional

    Returns
    -------
    MPUImplicit or RBFImplicit: callable (m, k) points -> (m,) f, f > 0 inside
    """
    points, normals, method = _prepared(points, normals, method)
    return _fit(points, normals, method, error_bound, progress)

