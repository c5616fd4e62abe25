"""Polyharmonic radial basis functions (Carr et al., SIGGRAPH 2001) on overlapping patches, blended by a partition
of unity, in k = 2 to 5 dimensions: one RBF implicit for every source that needs one.

One RBF through m constraints costs O(m^3) to solve and O(m) per evaluated point; here the box of the constraints
is split like a quadtree (2D) or an octree (3D), 2^k children a cell, until each patch's ball holds at most
:data:`PATCH_CENTRES` of them (but no patch narrower than ``min_patch``: contours need patches that see several
slices).  Each patch fits its own
RBF, f_i(y) = sum_j w_j phi(|y - c_j|) + a . y + b (a polynomial of degree 1, k + 1 terms), to the constraints in
its ball; f is their average weighted by w(d / r) = (1 - t)^4 (4 t + 1) (Wendland's C2 function, t = d / r), so
that an evaluation costs a few patches, whatever the number of constraints.  Few constraints give one patch: the
global RBF.

:func:`fit_rbf` is the implicit of scattered oriented points (method 'rbf'); the labelled contours build their
constraints themselves and call :func:`fit_partition`.

Convention: f > 0 inside, about the signed distance (input units) near f = 0.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import linalg
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist, squareform

from ..compiled import one_blas_thread, threaded_map
from ..errors import InvalidInputError, check_choice, check_number, check_points
from ..grid.sampled import bounding_box, box_depth, box_depth_gradient
from .normals import unit_normals
from .rbf_sums import KERNEL_NUMBERS, patch_sums
from ..parameters import KERNELS
from ..progress import ProgressCallback, report

#: RBF kernels phi(r) (with a linear polynomial): r (biharmonic in 3D), r^3 (triharmonic), r^2 log r (the thin
#: plate, biharmonic in 2D).
#: the kernel of method 'rbf' by dimension (benchmarks/rbf_accuracy.py): in 2D the thin plate, the 2D biharmonic
#: (r^3 lies 1.5 to 2 times closer to the annulus, but its far field falls below minus the distance to the box: -43
#: at 29 from it); in 3D r^3 (2 to 8 times closer than the thin plate on 1,500 to 5,000 points of a sphere, as
#: close on 300 points or 7 slices, half the time to evaluate).
SCATTERED_KERNEL = {2: "thin_plate", 3: "cubic", 4: "cubic", 5: "cubic"}
#: most points method 'rbf' accepts: its cost grows about linearly (0.6 ms per 3D point for the fit and a grid I
#: of 67^3 nodes, single-threaded BLAS: 4.5 s at 5,000 points, 12 s at 20,000), but 20 to 40 times the MPU's on the
#: same points; dense samples are the MPU's.
MAX_RBF_POINTS = 50000
#: a patch is split while its ball holds more constraints than this (on-, off-surface and interior points).
PATCH_CENTRES = 1200
#: a patch's ball grows until it holds at least this many constraints, and its points span the k dimensions.
MIN_PATCH_CENTRES = 600
#: a patch's radius is this x the half-diagonal of its cell (neighbouring balls overlap).
OVERLAP = 1.0
#: points evaluated together (one k-d tree of them per chunk finds each patch's points).
_CHUNK_POINTS = 1 << 17


def _kernel(r: np.ndarray, kernel: str) -> np.ndarray:
    """phi(r), in place on r."""
    if kernel == "cubic":
        cube = r * r
        cube *= r
        return cube
    if kernel == "linear":
        return r
    safe = np.where(r > 0, r, 1.0)   # thin plate r^2 log r, 0 at r = 0
    return np.multiply(r * r, np.log(safe), out=r)


@dataclass(frozen=True, eq=False)
class LocalRBF:
    """f(x) = sum_j w_j phi(|y - c_j|) + a . y + b, y = (x - shift) / scale: one patch's polyharmonic RBF.

    centres (m, k) scaled; weights (m,); polynomial (k + 1,) b and a; kernel; shift (k,), scale float (input units).
    """

    centres: np.ndarray
    weights: np.ndarray
    polynomial: np.ndarray
    kernel: str
    shift: np.ndarray
    scale: float

    def value_and_slope(self, x: np.ndarray, slope: bool):
        """(q,) f and, with ``slope``, (q, k) its gradient per input unit, at (q, k) points."""
        y = np.ascontiguousarray((x - self.shift) / self.scale)
        value, factors, moments = patch_sums(y, self.centres, self.weights, self.polynomial,
                                             KERNEL_NUMBERS[self.kernel], slope)
        if not slope:
            return value, None
        return value, (y * factors[:, None] - moments + self.polynomial[1:]) / self.scale


def _wendland(t: np.ndarray):
    """w(t) = (1 - t)^4 (4 t + 1) for t < 1, else 0, and w'(t)."""
    s = np.clip(1.0 - t, 0.0, None)
    return s ** 4 * (4.0 * t + 1.0), -20.0 * t * s ** 3


@dataclass(frozen=True, eq=False)
class RBFImplicit:
    """The partition of unity of :class:`LocalRBF` patches: f(x) = sum_i w_i(x) f_i(x) / sum_i w_i(x), > 0 inside;
    with a box, f <= the depth in it (so that every point far from the data is outside).

    Attributes
    ----------
    centres : (p, k) float64, the patches' centres; radii : (p,) float64, their balls' radii (input units; one
        patch: inf)
    patches : (p,) LocalRBF
    lower, upper : (k,) float64 or None, the box f is clamped by (method 'rbf': the data's bounding box)
    """

    centres: np.ndarray
    radii: np.ndarray
    patches: tuple
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @property
    def dim(self) -> int:
        return self.centres.shape[1]

    @cached_property
    def _patch_tree(self) -> cKDTree:
        return cKDTree(self.centres)

    def __call__(self, x) -> np.ndarray:
        """(m,) f at (m, k) points, input units."""
        x = check_points(x, "x", dims=(self.dim,))
        value = self._blend(x, slope=False)[0]
        return value if self.lower is None else np.minimum(value, box_depth(x, self.lower, self.upper))

    def gradient(self, x) -> np.ndarray:
        """(m, k) analytic gradient of f (per input unit)."""
        x = check_points(x, "x", dims=(self.dim,))
        value, slope = self._blend(x, slope=True)
        if self.lower is not None:
            depth, box_slope = box_depth_gradient(x, self.lower, self.upper)
            clamp = depth < value
            slope[clamp] = box_slope[clamp]
        return slope

    def _blend(self, x: np.ndarray, slope: bool):
        value, gradient = np.empty(len(x)), np.empty(x.shape) if slope else None
        for start in range(0, len(x), _CHUNK_POINTS):
            part = x[start:start + _CHUNK_POINTS]
            total, weights = np.zeros(len(part)), np.zeros(len(part))
            total_slope, weight_slope = (np.zeros(part.shape), np.zeros(part.shape)) if slope else (0, 0)
            members = cKDTree(part).query_ball_point(self.centres, self.radii, return_sorted=False)
            for centre, radius, patch, index in zip(self.centres, self.radii, self.patches, members):
                if not index:   # summed in the patches' order; each patch's sums on every thread (rbf_sums)
                    continue
                index, w, f, df, direction = _patch_terms(part, slope, centre, radius, patch, np.asarray(index))
                total[index] += w * f
                weights[index] += w
                if slope:
                    total_slope[index] += direction * f[:, None] + w[:, None] * df
                    weight_slope[index] += direction
            lonely = np.flatnonzero(weights <= 0)   # beyond every ball: the nearest patch alone
            if len(lonely):
                nearest = self._patch_tree.query(part[lonely])[1]
                for patch_index in np.unique(nearest):
                    chosen = lonely[nearest == patch_index]
                    f, df = self.patches[patch_index].value_and_slope(part[chosen], slope)
                    total[chosen], weights[chosen] = f, 1.0
                    if slope:
                        total_slope[chosen], weight_slope[chosen] = df, 0.0
            value[start:start + len(part)] = total / weights
            if slope:
                gradient[start:start + len(part)] = (total_slope - value[start:start + len(part), None]
                                                     * weight_slope) / weights[:, None]
        return value, gradient


def _patch_terms(part, slope: bool, centre, radius: float, patch: LocalRBF, index):
    """One patch's terms at the (q,) ``index`` of the (m, k) points ``part`` in its ball: the index, the weights w
    and f (q,), and with ``slope`` grad f and grad w (q, k)."""
    offset = part[index] - centre
    distance = np.sqrt(np.einsum("ij,ij->i", offset, offset))
    w, dw = _wendland(distance / radius)
    f, df = patch.value_and_slope(part[index], slope)
    direction = dw[:, None] * offset / (radius * np.maximum(distance, 1e-300))[:, None] if slope else None
    return index, w, f, df, direction


def _solve(centres, values, kernel: str, smoothing: float, shift, scale: float, what: str) -> LocalRBF:
    """The RBF through (m, k) ``centres`` with ``values``, in coordinates (x - shift) / scale; ``what`` (e.g.
    "120 contour points") names the data in the message of a singular system."""
    y = (centres - shift) / scale
    size, terms = len(y), y.shape[1] + 1
    matrix = np.zeros((size + terms, size + terms))
    matrix[:size, :size] = _kernel(squareform(pdist(y)), kernel)
    matrix[np.arange(size), np.arange(size)] += smoothing
    matrix[:size, size] = matrix[size, :size] = 1.0
    matrix[:size, size + 1:] = y
    matrix[size + 1:, :size] = y.T
    right = np.r_[values, np.zeros(terms)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", linalg.LinAlgWarning)   # judged by the residual below
            solution = linalg.lu_solve(linalg.lu_factor(matrix, check_finite=False), right, check_finite=False)
    except (linalg.LinAlgError, ValueError) as error:
        solution, reason = None, str(error)
    else:
        residual = float(np.abs(matrix @ solution - right).max())
        reason = f"residual {residual:.3g}"
        if not residual <= 1e-6 * max(1.0, float(np.abs(values).max())):
            solution = None
    if solution is None:
        raise InvalidInputError(
            f"the RBF system of {what} cannot be solved ({reason}); are points repeated (within rounding), or all "
            + ("in one plane?" if y.shape[1] == 3 else "on one line?"))
    return LocalRBF(centres=y, weights=solution[:size], polynomial=solution[size:], kernel=kernel,
                    shift=np.asarray(shift, dtype=np.float64), scale=float(scale))


def _spans_space(points: np.ndarray) -> bool:
    """Whether (q, k) points spread in all k dimensions (the smallest spread at least 5 % of the largest)."""
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    dim = points.shape[1]
    return len(points) >= dim + 1 and spread[dim - 1] > 0.05 * spread[0]


def _patches(constraints: np.ndarray, min_radius: float):
    """(p, k) centres and (p,) radii of the patches: the leaves of a quadtree (2D) or octree (3D) over the
    constraints' box, split while a ball holds more than :data:`PATCH_CENTRES` and its radius stays at least
    ``min_radius``; each ball grown until it holds :data:`MIN_PATCH_CENTRES` (or all) and spans k dimensions."""
    tree = cKDTree(constraints)
    dim = constraints.shape[1]
    corners = np.array(np.meshgrid(*[(-1, 1)] * dim)).T.reshape(-1, dim)
    lower, upper = constraints.min(axis=0), constraints.max(axis=0)
    side = float(np.max(upper - lower)) * 1.001 + 1e-12
    cells, leaves = [((lower + upper) / 2, side)], []
    while cells:
        centre, side = cells.pop()
        radius = OVERLAP * side * np.sqrt(dim) / 2
        if radius / 2 >= min_radius and tree.query_ball_point(centre, radius, return_length=True) > PATCH_CENTRES:
            cells.extend((centre + side / 4 * np.array(corner), side / 2) for corner in corners)
        else:
            leaves.append((centre, radius))
    if len(leaves) == 1:
        return np.array([leaves[0][0]]), np.array([np.inf])
    centres, radii = [], []
    for centre, radius in leaves:
        needed = min(MIN_PATCH_CENTRES, len(constraints))
        nearest = tree.query(centre, k=needed)[0]
        radius = max(radius, float(np.max(nearest)) * 1.001)
        while True:
            inside = constraints[tree.query_ball_point(centre, radius)]
            if _spans_space(inside) or len(inside) == len(constraints):
                break
            radius *= 1.25
        centres.append(centre)
        radii.append(radius)
    return np.array(centres), np.array(radii)


def fit_partition(constraints, values, *, kernel: str, smoothing: float = 0.0, min_patch: float = 0.0,
                  shared: int = 0, frame, what: str, box=None, near=None,
                  progress: ProgressCallback = None) -> RBFImplicit:
    """The partition-of-unity RBF through (m, k) ``constraints`` with (m,) ``values``.

    Parameters
    ----------
    constraints : (m, k) float64, input units, distinct; values : (m,) float64
    kernel : one of :data:`KERNELS`; smoothing : float >= 0, added to each kernel matrix's diagonal (0 interpolates)
    min_patch : float, input units: no patch's radius is below this; 0 splits by the number of constraints alone
    shared : the last ``shared`` constraints belong to every patch (a valve's centre inside its cavity)
    frame : (shift (k,), scale float): the coordinates of the global RBF when there is one patch
    what : names the data in the message of a singular system ("120 contour points")
    box : (lower (k,), upper (k,)) the function is clamped by (f <= depth in the box), or None
    near : (q, k) float64, optional: the function will be evaluated at these points only; only the patches it
        takes there are solved (the values there are the whole function's, bit for bit; elsewhere they are not)
    progress : callable(fraction, message), optional, called as the patches are solved

    Returns
    -------
    RBFImplicit
    """
    centres, radii = _patches(constraints, min_patch)
    if near is not None and len(centres) > 1:
        chosen = _patches_taken(centres, radii, np.asarray(near, dtype=np.float64))
        centres, radii = centres[chosen], radii[chosen]
    tree = cKDTree(constraints)
    everywhere = np.arange(len(constraints) - shared, len(constraints))

    def solve(patch):
        centre, radius = patch
        index = np.arange(len(constraints)) if np.isinf(radius) else np.union1d(
            tree.query_ball_point(centre, radius), everywhere)
        shift, scale = frame if np.isinf(radius) else (centre, 2.0 * radius)
        return _solve(constraints[index], values[index], kernel, smoothing, shift, scale, what)

    patches = []
    with one_blas_thread():
        for patch in threaded_map(solve, zip(centres, radii)):
            patches.append(patch)
            report(progress, len(patches) / len(centres), f"fitted RBF patch {len(patches)} of {len(centres)}")
    lower, upper = (None, None) if box is None else box
    return RBFImplicit(centres=centres, radii=radii, patches=tuple(patches), lower=lower, upper=upper)


def _patches_taken(centres, radii, points) -> np.ndarray:
    """(p,) bool: the patches (centres (p, k), radii (p,)) whose ball holds one of the (q, k) ``points``, and each
    point's nearest patch (the one :meth:`RBFImplicit._blend` takes for a point beyond every ball)."""
    taken = np.zeros(len(centres), bool)
    taken[cKDTree(centres).query(points)[1]] = True
    for patch, index in enumerate(cKDTree(points).query_ball_point(centres, radii, return_sorted=False)):
        taken[patch] |= bool(index)
    return taken


def fit_rbf(points, normals, *, offset=None, smoothing: float = 0.0, kernel=None,
            progress: ProgressCallback = None) -> RBFImplicit:
    """The RBF implicit of sparse oriented points (Carr et al. 2001), k = 2 to 5: method 'rbf'.

    f is 0 on the points and +delta_i / -delta_i at p_i -/+ delta_i n_i (inside / outside), with
    delta_i = min(offset, half the distance from p_i to its nearest neighbour), so off-surface points never pass
    another sample; clamped by the depth in the points' bounding box.  More than :data:`PATCH_CENTRES` constraints
    (400 points) are fitted on patches (see the module docstring), so the cost grows about linearly.

    Parameters
    ----------
    points : (n, k) float64, input units, distinct, n <= :data:`MAX_RBF_POINTS`
    normals : (n, k) float64, outward
    offset : float, input units; default 1 % of the bounding-box diagonal
    smoothing : float >= 0, added to the diagonal of each kernel matrix (0 interpolates)
    kernel : one of :data:`KERNELS`; default :data:`SCATTERED_KERNEL` of the dimension
    progress : callable(fraction, message), optional (raise Cancelled in it to stop)

    Returns
    -------
    RBFImplicit, callable (m, k) -> (m,), f > 0 inside
    """
    points = check_points(points)
    if len(points) > MAX_RBF_POINTS:
        raise InvalidInputError(
            f"method 'rbf' accepts at most {MAX_RBF_POINTS} points (dense samples are the MPU's: 20 to 40 times "
            f"faster), got {len(points)}; use method='mpu' (3D) or thin the points")
    normals = unit_normals(normals, points.shape)
    kernel = SCATTERED_KERNEL[points.shape[1]] if kernel is None else check_choice(kernel, "kernel", KERNELS)
    lower, upper, diagonal = bounding_box(points)
    offset = 0.01 * diagonal if offset is None else check_number(offset, "offset", low=0, low_open=True)
    smoothing = check_number(smoothing, "smoothing", low=0)
    spacing, _ = cKDTree(points).query(points, k=2)
    if not (spacing[:, 1] > 0).all():
        raise InvalidInputError("points contains duplicate points; remove them (points_to_implicit does)")
    delta = np.minimum(offset, 0.5 * spacing[:, 1])[:, None]
    constraints = np.vstack([points, points - delta * normals, points + delta * normals])
    values = np.r_[np.zeros(len(points)), delta[:, 0], -delta[:, 0]]
    return fit_partition(constraints, values, kernel=kernel, smoothing=smoothing,
                         frame=(points.mean(axis=0), diagonal), what=f"{len(points)} points", box=(lower, upper),
                         progress=progress)
