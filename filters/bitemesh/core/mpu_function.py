"""The fitted Multilevel Partition of Unity implicit (Ohtake et al. 2003; fitted by :func:`bitemesh.core.mpu.fit_mpu`):
the leaves' local quadrics blended by quadratic B-spline weights, clamped by the depth in the data's bounding box,
with its analytic gradient.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from .errors import check_points
from .grid import box_depth, box_depth_gradient

#: MPU evaluation points handled at once (bounds the memory of the point-leaf pairs).
_EVALUATION_CHUNK = 1 << 15
#: point-leaf pairs whose terms are computed at once (cache-sized).
_PAIR_BLOCK = 1 << 16


def _bspline(t: np.ndarray) -> np.ndarray:
    """The quadratic B-spline b(t) for t >= 0, supported on [0, 1.5)."""
    return np.where(t <= 0.5, 0.75 - t * t, 0.5 * np.square(np.maximum(1.5 - t, 0.0)))


def _bspline_slope_ratio(t: np.ndarray) -> np.ndarray:
    """b'(t) / t for t >= 0 (finite at t = 0), so that grad b(1.5 |y|) = 2.25 b'(t)/t y."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(t <= 0.5, -2.0, np.where(t < 1.5, (t - 1.5) / t, 0.0))


def _quadric(y, c) -> np.ndarray:
    """Value of the quadric with coefficients c[0..9] (in the _monomials basis) at y = (y[0], y[1], y[2])."""
    a, b, z = y
    return (a * (c[0] * a + c[3] * b + c[4] * z + c[6]) + b * (c[1] * b + c[5] * z + c[7])
            + z * (c[2] * z + c[8]) + c[9])


def _quadric_gradient(y, c) -> np.ndarray:
    """(3, ...) gradient with respect to y of the quadric with coefficients c[0..9] at y = (y[0], y[1], y[2])."""
    a, b, z = y
    return np.stack([2 * c[0] * a + c[3] * b + c[4] * z + c[6],
                     2 * c[1] * b + c[3] * a + c[5] * z + c[7],
                     2 * c[2] * z + c[4] * a + c[5] * b + c[8]])


@dataclass(frozen=True, eq=False)
class MPUImplicit:
    """The blended local fits f(x) = sum_i w_i(x) Q_i(x) / sum_i w_i(x), clamped by the bounding-box depth.

    Attributes
    ----------
    centres : (L, 3) float64, leaf cell centres c_i
    radii : (L,) float64, support radii R_i; w_i(x) = b(3 |x - c_i| / (2 R_i))
    coefficients : (L, 10) float64, Q_i in the monomials x^2, y^2, z^2, xy, xz, yz, x, y, z, 1 of
        (x - c_i) / R_i; Q_i in input units, > 0 inside
    points : (n, 3) float64, the data points (f = -distance to them where no leaf reaches)
    lower, upper : (3,) float64, the data's bounding box; f <= depth in it
    """

    centres: np.ndarray
    radii: np.ndarray
    coefficients: np.ndarray
    points: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @cached_property
    def _groups(self) -> list:
        """(radius, leaf indices, k-d tree of their centres) per distinct support radius."""
        values, group = np.unique(self.radii, return_inverse=True)
        members = [np.flatnonzero(group == g) for g in range(len(values))]
        return [(radius, leaf, cKDTree(self.centres[leaf])) for radius, leaf in zip(values, members)]

    @cached_property
    def _data_tree(self) -> cKDTree:
        return cKDTree(self.points)

    @cached_property
    def _centre_rows(self) -> np.ndarray:
        return np.ascontiguousarray(self.centres.T)

    @cached_property
    def _coefficient_rows(self) -> np.ndarray:
        return np.ascontiguousarray(self.coefficients.T)

    def __call__(self, x) -> np.ndarray:
        """(m,) f at (m, 3) points x."""
        return self._evaluate(x, gradient=False)[0]

    def gradient(self, x) -> np.ndarray:
        """(m, 3) analytic gradient of f at (m, 3) points x."""
        return self._evaluate(x, gradient=True)[1]

    def _evaluate(self, x, *, gradient: bool):
        x = check_points(x, "x", dims=(3,))
        value = np.empty(len(x))
        slope = np.empty_like(x) if gradient else None
        for start in range(0, len(x), _EVALUATION_CHUNK):
            part = slice(start, start + _EVALUATION_CHUNK)
            value[part], grad = self._blend(x[part], gradient)
            if gradient:
                slope[part] = grad
        if gradient:
            depth, box_slope = box_depth_gradient(x, self.lower, self.upper)
        else:
            depth = box_depth(x, self.lower, self.upper)
        clamp = depth < value
        value[clamp] = depth[clamp]
        if gradient:
            slope[clamp] = box_slope[clamp]
        return value, slope

    def _blend(self, x: np.ndarray, gradient: bool):
        """f (and its gradient) of the partition of unity at (m, 3) points; -distance to the data where uncovered."""
        there = cKDTree(x)
        found = [(members, tree.sparse_distance_matrix(there, radius, output_type="ndarray"))
                 for radius, members, tree in self._groups]
        leaf = np.concatenate([members[pairs["i"]] for members, pairs in found])
        at = np.concatenate([pairs["j"] for _, pairs in found])
        distance = np.concatenate([pairs["v"] for _, pairs in found])
        # Sums over the pairs, in cache-sized blocks: w, w Q (and w grad Q, grad w, Q grad w).
        sums = np.zeros((11 if gradient else 2, len(x)))
        for start in range(0, len(leaf), _PAIR_BLOCK):
            block = slice(start, start + _PAIR_BLOCK)
            sums += self._pair_sums(x, leaf[block], at[block], distance[block], gradient)
        total = sums[0]
        covered = total > 0
        value = sums[1]
        value[covered] /= total[covered]
        slope = None
        if gradient:
            # grad f = (sum w_i grad Q_i + sum (Q_i - f) grad w_i) / sum w_i
            slope = (sums[2:5] + sums[8:11] - value * sums[5:8]).T
            slope[covered] /= total[covered, None]
        if not covered.all():
            distance_out, nearest = self._data_tree.query(x[~covered])
            value[~covered] = -distance_out
            if gradient:
                slope[~covered] = (self.points[nearest] - x[~covered]) / np.maximum(distance_out, 1e-300)[:, None]
        return value, slope

    def _pair_sums(self, x, leaf, at, distance, gradient):
        """(2 or 11, m) sums per point of w, w Q (and w grad Q, grad w, Q grad w) over the given point-leaf pairs."""
        scale = 1.0 / self.radii[leaf]
        t = 1.5 * scale * distance
        # np.take gathers columns several times faster than fancy indexing [:, index].
        y = (np.take(x.T, at, axis=1) - np.take(self._centre_rows, leaf, axis=1)) * scale   # (3, pairs)
        coef = np.take(self._coefficient_rows, leaf, axis=1)                                 # (10, pairs)
        weight = _bspline(t)
        local = _quadric(y, coef)
        terms = [weight, weight * local]
        if gradient:
            weight_slope = 2.25 * _bspline_slope_ratio(t) * scale * y
            terms += [*(weight * scale * _quadric_gradient(y, coef)), *weight_slope, *(local * weight_slope)]
        return np.stack([np.bincount(at, term, minlength=len(x)) for term in terms])
