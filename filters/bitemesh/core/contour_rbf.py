"""One implicit function per contour surface: polyharmonic RBFs (Carr et al., SIGGRAPH 2001) on overlapping
patches, blended by a partition of unity, so that the cost grows about linearly with the number of points.

The constraints: f = 0 on the contour points, +delta inside and -delta outside at p -/+ delta n (n the in-plane
outward normal, :func:`off_surface_offsets`), and optional interior points (a valve's centre inside its cavity).
One RBF through every constraint costs O(m^3) to solve and O(m) per evaluated point (m = 3 n); here the box of the
constraints is split like an octree until each patch's ball holds at most :data:`PATCH_CENTRES` of them, but no
patch is narrower than the gap between the slices (each must see contours on several slices).  Each patch fits its
own RBF to the constraints in its ball; f is their average weighted by w(d / r) = (1 - t)^4 (4 t + 1) (Wendland's
C2 function, t = d / r), so every evaluation costs a few patches' centres, whatever n.  Few constraints give one
patch: the global RBF.

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

from .errors import InvalidInputError, check_choice, check_number, check_points

#: RBF kernels phi(r) (with a linear polynomial); "linear" (biharmonic) is the default (see benchmarks/bivme.py).
KERNELS = ("linear", "cubic", "thin_plate")
#: a patch is split while its ball holds more constraints than this (on-, off-surface and interior points).
PATCH_CENTRES = 1200
#: a patch's ball grows until it holds at least this many constraints, and its points span three dimensions.
MIN_PATCH_CENTRES = 600
#: a patch's radius is this x the half-diagonal of its octree cell (neighbouring balls overlap).
OVERLAP = 1.0
#: the points are fitted thinned to this x the off-surface offset apart (contours traced on 1.4 mm pixels are about
#: 3 mm apart; a denser resampling adds time, not shape).
THIN_PER_OFFSET = 0.4
#: kernel entries per chunk when an RBF is evaluated: cache-sized (64 k entries are 8 times faster than 4 M).
_CHUNK_ENTRIES = 1 << 16
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


def _kernel_slope(r: np.ndarray, kernel: str) -> np.ndarray:
    """phi'(r) / r (finite at r = 0 where the kernel is smooth)."""
    if kernel == "cubic":
        return 3.0 * r
    if kernel == "linear":
        return 1.0 / np.where(r > 0, r, np.inf)
    return 2.0 * np.log(np.where(r > 0, r, 1.0)) + 1.0


@dataclass(frozen=True, eq=False)
class LocalRBF:
    """f(x) = sum_j w_j phi(|y - c_j|) + a . y + b, y = (x - shift) / scale: one patch's polyharmonic RBF.

    centres (m, 3) scaled; weights (m,); polynomial (4,) b and a; kernel; shift (3,), scale float (input units).
    """

    centres: np.ndarray
    weights: np.ndarray
    polynomial: np.ndarray
    kernel: str
    shift: np.ndarray
    scale: float

    @cached_property
    def _centre_norms(self) -> np.ndarray:
        return np.einsum("md,md->m", self.centres, self.centres)

    @cached_property
    def _centre_rows(self) -> np.ndarray:
        return np.ascontiguousarray(-2.0 * self.centres.T)

    def value_and_slope(self, x: np.ndarray, slope: bool):
        """(k,) f and, with ``slope``, (k, 3) its gradient per input unit, at (k, 3) points."""
        y = (x - self.shift) / self.scale
        value, gradient = np.empty(len(y)), np.empty((len(y), 3)) if slope else None
        step = max(1, _CHUNK_ENTRIES // len(self.centres))
        for start in range(0, len(y), step):
            part = y[start:start + step]
            r = part @ self._centre_rows   # |y - c|^2 = |y|^2 + |c|^2 - 2 y . c, by BLAS
            r += self._centre_norms
            r += np.einsum("md,md->m", part, part)[:, None]
            r = np.sqrt(np.maximum(r, 0.0, out=r), out=r)
            if slope:
                factor = _kernel_slope(r, self.kernel) * self.weights
                gradient[start:start + len(part)] = (part * factor.sum(axis=1)[:, None] - factor @ self.centres
                                                     + self.polynomial[1:]) / self.scale
            value[start:start + len(part)] = (_kernel(r, self.kernel) @ self.weights + self.polynomial[0]
                                              + part @ self.polynomial[1:])
        return value, gradient


def _wendland(t: np.ndarray):
    """w(t) = (1 - t)^4 (4 t + 1) for t < 1, else 0, and w'(t)."""
    s = np.clip(1.0 - t, 0.0, None)
    return s ** 4 * (4.0 * t + 1.0), -20.0 * t * s ** 3


@dataclass(frozen=True, eq=False)
class ContourRBF:
    """The partition of unity of :class:`LocalRBF` patches: f(x) = sum_i w_i(x) f_i(x) / sum_i w_i(x), > 0 inside.

    Attributes
    ----------
    centres : (p, 3) float64, the patches' centres; radii : (p,) float64, their balls' radii (input units)
    patches : (p,) LocalRBF
    """

    centres: np.ndarray
    radii: np.ndarray
    patches: tuple

    @cached_property
    def _patch_tree(self) -> cKDTree:
        return cKDTree(self.centres)

    def __call__(self, x) -> np.ndarray:
        """(m,) f at (m, 3) points, input units."""
        return self._blend(check_points(x, "x", dims=(3,)), slope=False)[0]

    def gradient(self, x) -> np.ndarray:
        """(m, 3) analytic gradient of f (per input unit)."""
        return self._blend(check_points(x, "x", dims=(3,)), slope=True)[1]

    def _blend(self, x: np.ndarray, slope: bool):
        value, gradient = np.empty(len(x)), np.empty((len(x), 3)) if slope else None
        for start in range(0, len(x), _CHUNK_POINTS):
            part = x[start:start + _CHUNK_POINTS]
            total, weights = np.zeros(len(part)), np.zeros(len(part))
            total_slope, weight_slope = (np.zeros((len(part), 3)), np.zeros((len(part), 3))) if slope else (0, 0)
            members = cKDTree(part).query_ball_point(self.centres, self.radii, return_sorted=False)
            for centre, radius, patch, index in zip(self.centres, self.radii, self.patches, members):
                if not index:
                    continue
                index = np.asarray(index)
                offset = part[index] - centre
                distance = np.sqrt(np.einsum("ij,ij->i", offset, offset))
                w, dw = _wendland(distance / radius)
                f, df = patch.value_and_slope(part[index], slope)
                total[index] += w * f
                weights[index] += w
                if slope:
                    direction = dw[:, None] * offset / (radius * np.maximum(distance, 1e-300))[:, None]
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


def _solve(centres, values, kernel: str, smoothing: float, shift, scale: float, count: int) -> LocalRBF:
    """The RBF through (m, 3) ``centres`` with ``values``, in coordinates (x - shift) / scale; ``count`` (the
    surface's number of points) names the surface in the message of a singular system."""
    y = (centres - shift) / scale
    size = len(y)
    matrix = np.zeros((size + 4, size + 4))
    matrix[:size, :size] = _kernel(squareform(pdist(y)), kernel)
    matrix[np.arange(size), np.arange(size)] += smoothing
    matrix[:size, size] = matrix[size, :size] = 1.0
    matrix[:size, size + 1:] = y
    matrix[size + 1:, :size] = y.T
    right = np.r_[values, np.zeros(4)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", linalg.LinAlgWarning)   # judged by the residual below
            solution = linalg.solve(matrix, right, assume_a="sym")
    except (linalg.LinAlgError, ValueError) as error:
        solution, reason = None, str(error)
    else:
        residual = float(np.abs(matrix @ solution - right).max())
        reason = f"residual {residual:.3g}"
        if not residual <= 1e-6 * max(1.0, float(np.abs(values).max())):
            solution = None
    if solution is None:
        raise InvalidInputError(
            f"the RBF system of {count} contour points cannot be solved ({reason}); are points repeated "
            "(within rounding), or all in one plane?")
    return LocalRBF(centres=y, weights=solution[:size], polynomial=solution[size:], kernel=kernel,
                    shift=np.asarray(shift, dtype=np.float64), scale=float(scale))


def _spans_space(points: np.ndarray) -> bool:
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return len(points) >= 4 and spread[2] > 0.05 * spread[0]


def _patches(constraints: np.ndarray, min_radius: float):
    """(p, 3) centres and (p,) radii of the patches: the leaves of an octree over the constraints' box, split
    while a ball holds more than :data:`PATCH_CENTRES` and its radius stays at least ``min_radius``; each ball
    grown until it holds :data:`MIN_PATCH_CENTRES` (or all) and spans three dimensions."""
    tree = cKDTree(constraints)
    lower, upper = constraints.min(axis=0), constraints.max(axis=0)
    side = float(np.max(upper - lower)) * 1.001 + 1e-12
    cells, leaves = [((lower + upper) / 2, side)], []
    while cells:
        centre, side = cells.pop()
        radius = OVERLAP * side * np.sqrt(3) / 2
        if radius / 2 >= min_radius and tree.query_ball_point(centre, radius, return_length=True) > PATCH_CENTRES:
            cells.extend((centre + side / 4 * np.array(corner), side / 2)
                         for corner in np.array(np.meshgrid(*[(-1, 1)] * 3)).T.reshape(-1, 3))
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


def fit_contour_rbf(points, normals, *, kernel: str = "linear", offset: float = 4.0, smoothing: float = 0.0,
                    interior=None, min_patch: float = 0.0, min_spacing=None) -> ContourRBF:
    """The implicit of contour points with (in-plane) outward normals: RBFs on patches blended by a partition of
    unity (see the module docstring).

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

    Returns
    -------
    ContourRBF
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
    centres, radii = _patches(constraints, check_number(min_patch, "min_patch", low=0))
    tree = cKDTree(constraints)
    everywhere = np.arange(len(constraints) - (0 if interior is None else len(interior[0])), len(constraints))
    patches = []
    for centre, radius in zip(centres, radii):
        index = np.arange(len(constraints)) if np.isinf(radius) else np.union1d(
            tree.query_ball_point(centre, radius), everywhere)
        if np.isinf(radius):
            shift, scale = points.mean(axis=0), float(np.linalg.norm(np.ptp(points, axis=0)))
        else:
            shift, scale = centre, 2.0 * radius
        patches.append(_solve(constraints[index], values[index], kernel, smoothing, shift, scale, len(points)))
    return ContourRBF(centres=centres, radii=radii, patches=tuple(patches))
