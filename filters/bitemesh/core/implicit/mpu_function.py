"""The fitted Multilevel Partition of Unity implicit (Ohtake et al. 2003; fitted by
:func:`bitemesh.core.implicit.mpu.fit_mpu`): the leaves' local quadrics blended by quadratic B-spline weights, clamped
by the depth in the data's bounding box, with its analytic gradient.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from ..compiled import kernel
from ..errors import check_points
from ..grid.sampled import box_depth, box_depth_gradient

#: MPU evaluation points handled at once (bounds the memory of the buckets).
_EVALUATION_CHUNK = 1 << 15
#: the evaluation points are put in buckets of this many times the smallest support radius (or larger, so that
#: there are at most _BUCKETS_PER_POINT buckets a point).
_BUCKET_SIDE = 1.0
_BUCKETS_PER_POINT = 8


@kernel
def _bspline(t):
    """The quadratic B-spline b(t) for t >= 0, supported on [0, 1.5)."""
    if t <= 0.5:
        return 0.75 - t * t
    return 0.5 * np.square(max(1.5 - t, 0.0))


@kernel
def _bspline_weights(t):
    """:func:`_bspline` of each of the (n,) values ``t``."""
    weights = np.empty_like(t)
    for i in range(len(t)):
        weights[i] = _bspline(t[i])
    return weights


@kernel
def _bspline_slope_ratio(t):
    """b'(t) / t for t >= 0 (finite at t = 0), so that grad b(1.5 |y|) = 2.25 b'(t)/t y."""
    if t <= 0.5:
        return -2.0
    return (t - 1.5) / t if t < 1.5 else 0.0


@kernel
def _quadric(a, b, z, c):
    """Value of the quadric with coefficients c[0..9] (in the _monomials basis) at y = (a, b, z): scalars, or arrays
    with c (10, ...)."""
    return (a * (c[0] * a + c[3] * b + c[4] * z + c[6]) + b * (c[1] * b + c[5] * z + c[7])
            + z * (c[2] * z + c[8]) + c[9])


@kernel
def _quadric_gradient(a, b, z, c):
    """The gradient (three components) with respect to y of :func:`_quadric` at y = (a, b, z)."""
    return (2 * c[0] * a + c[3] * b + c[4] * z + c[6],
            2 * c[1] * b + c[3] * a + c[5] * z + c[7],
            2 * c[2] * z + c[4] * a + c[5] * b + c[8])


@kernel
def _leaf_quadric(a, b, z, first, second, join):
    """A leaf's local function at y = (a, b, z), and whether ``second`` rather than ``first`` (the (10,) quadrics)
    gives it there: ``first`` alone, or where the leaf is a sharp edge (``join`` 1: the union of two sheets, max;
    -1: their intersection, min) the larger or smaller of the two."""
    value = _quadric(a, b, z, first)
    if join == 0:
        return value, False
    other = _quadric(a, b, z, second)
    if (other > value) == (join > 0):
        return other, True
    return value, False


@kernel
def _buckets(x, side):
    """The (m, 3) points in cubic buckets of ``side`` from their lower corner: (lower, shape (3,), start (B + 1,),
    order (m,)); the points of bucket (i, j, l) (C order, number u) are order[start[u]:start[u + 1]]."""
    lower = np.empty(3)
    shape = np.empty(3, np.int64)
    for d in range(3):
        lower[d] = x[:, d].min()
        shape[d] = int((x[:, d].max() - lower[d]) / side) + 1
    bucket = np.empty(len(x), np.int64)
    for p in range(len(x)):
        u = 0
        for d in range(3):
            u = u * shape[d] + min(int((x[p, d] - lower[d]) / side), shape[d] - 1)
        bucket[p] = u
    start = np.zeros(shape[0] * shape[1] * shape[2] + 1, np.int64)
    for p in range(len(x)):
        start[bucket[p] + 1] += 1
    for u in range(1, len(start)):
        start[u] += start[u - 1]
    filled = start[:-1].copy()
    order = np.empty(len(x), np.int64)
    for p in range(len(x)):
        order[filled[bucket[p]]] = p
        filled[bucket[p]] += 1
    return lower, shape, start, order


@kernel
def _blend_sums(x, centres, radii, coefficients, second, join, gradient, side):
    """(2 or 11, m) the sums at the (m, 3) points x of w, w Q (and w grad Q, grad w, Q grad w) over the leaves
    whose support holds them, leaf after leaf: each leaf visits the buckets (:func:`_buckets`) its ball overlaps."""
    lower, shape, start, order = _buckets(x, side)
    sums = np.zeros((11 if gradient else 2, len(x)))
    first = np.empty(3, np.int64)
    last = np.empty(3, np.int64)
    for leaf in range(len(radii)):
        radius = radii[leaf]
        empty = False
        for d in range(3):
            first[d] = max(int(np.floor((centres[leaf, d] - radius - lower[d]) / side)), 0)
            last[d] = min(int(np.floor((centres[leaf, d] + radius - lower[d]) / side)), shape[d] - 1)
            empty = empty or first[d] > last[d]
        if empty:
            continue
        scale = 1.0 / radius
        quadric, other, join_leaf = coefficients[leaf], second[leaf], join[leaf]
        for i in range(first[0], last[0] + 1):
            for j in range(first[1], last[1] + 1):
                row = (i * shape[1] + j) * shape[2]
                for u in range(row + first[2], row + last[2] + 1):
                    for at in order[start[u]:start[u + 1]]:
                        d0 = x[at, 0] - centres[leaf, 0]
                        d1 = x[at, 1] - centres[leaf, 1]
                        d2 = x[at, 2] - centres[leaf, 2]
                        t = 1.5 * scale * np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                        if t >= 1.5:
                            continue
                        weight = _bspline(t)
                        y0, y1, y2 = d0 * scale, d1 * scale, d2 * scale
                        local, from_other = _leaf_quadric(y0, y1, y2, quadric, other, join_leaf)
                        sums[0, at] += weight
                        sums[1, at] += weight * local
                        if gradient:
                            g0, g1, g2 = _quadric_gradient(y0, y1, y2, other if from_other else quadric)
                            ratio = 2.25 * _bspline_slope_ratio(t) * scale
                            sums[2, at] += weight * scale * g0
                            sums[3, at] += weight * scale * g1
                            sums[4, at] += weight * scale * g2
                            sums[5, at] += ratio * y0
                            sums[6, at] += ratio * y1
                            sums[7, at] += ratio * y2
                            sums[8, at] += local * ratio * y0
                            sums[9, at] += local * ratio * y1
                            sums[10, at] += local * ratio * y2
    return sums


@dataclass(frozen=True, eq=False)
class MPUImplicit:
    """The blended local fits f(x) = sum_i w_i(x) Q_i(x) / sum_i w_i(x), clamped by the bounding-box depth.

    Attributes
    ----------
    centres : (L, 3) float64, leaf cell centres c_i
    radii : (L,) float64, support radii R_i; w_i(x) = b(3 |x - c_i| / (2 R_i))
    coefficients : (L, 10) float64, Q_i in the monomials x^2, y^2, z^2, xy, xz, yz, x, y, z, 1 of
        (x - c_i) / R_i; Q_i in input units, > 0 inside
    second : (L, 10) float64, a second quadric where the leaf is a sharp edge (Ohtake's piecewise fits)
    join : (L,) int8, 0 (Q_i alone), 1 (max of the two quadrics: two sheets' union) or -1 (min: intersection)
    points : (n, 3) float64, the data points (f = -distance to them where no leaf reaches)
    lower, upper : (3,) float64, the data's bounding box; f <= depth in it
    """

    centres: np.ndarray
    radii: np.ndarray
    coefficients: np.ndarray
    second: np.ndarray
    join: np.ndarray
    points: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @cached_property
    def _data_tree(self) -> cKDTree:
        return cKDTree(self.points)

    @cached_property
    def _bucket_side(self) -> float:
        return _BUCKET_SIDE * float(self.radii.min())

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
        x = np.ascontiguousarray(x)
        extent = np.prod(np.ptp(x, axis=0) + self._bucket_side) if len(x) else 0.0
        side = max(self._bucket_side, float(extent / (_BUCKETS_PER_POINT * max(len(x), 1))) ** (1 / 3))
        sums = np.zeros((11 if gradient else 2, 0))
        if len(x):
            sums = _blend_sums(x, self.centres, self.radii, self.coefficients, self.second, self.join, gradient, side)
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
