"""The Multilevel Partition of Unity implicit of Ohtake, Belyaev, Alexa, Turk and Seidel (SIGGRAPH 2003), section
4.1 of the paper: an octree of local quadrics (bivariate where the samples are a sheet, general with auxiliary
points elsewhere), each cell subdivided until its fitting error is below the bound, blended by B-spline weights.
Clamped by the depth in the data's bounding box, so that every point far from the data is outside (f > 0 inside,
about the signed distance near f = 0).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from .errors import InvalidInputError, check_number, check_points
from .grid import bounding_box, box_depth, box_depth_gradient
from .normals import unit_normals
from .progress import ProgressCallback, report

#: fewest points an implicit is fitted to.
MIN_POINTS = 10
#: the octree root is the bounding cube of the points enlarged by this factor.
_ROOT_ENLARGEMENT = 1.1
#: support radius of a cell = this x the cell diagonal; grown in steps of _GROWTH.
_SUPPORT_FACTOR = 0.75
_GROWTH = 1.25
#: data points whose normals estimate the signed distance of an auxiliary point.
_AUX_NEIGHBOURS = 6
#: MPU evaluation points handled at once (bounds the memory of the point-leaf pairs).
_EVALUATION_CHUNK = 1 << 15
#: point-cell pairs assembled at once while fitting.
_FIT_PAIRS = 1 << 19
#: point-leaf pairs whose terms are computed at once (cache-sized).
_PAIR_BLOCK = 1 << 16

#: cell corners, then the centre, in half cell sides: Ohtake's auxiliary points.
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
_AUXILIARY = np.vstack([_CORNERS, np.zeros(3)])


def _bspline(t: np.ndarray) -> np.ndarray:
    """The quadratic B-spline b(t) for t >= 0, supported on [0, 1.5)."""
    return np.where(t <= 0.5, 0.75 - t * t, 0.5 * np.square(np.maximum(1.5 - t, 0.0)))


def _bspline_slope_ratio(t: np.ndarray) -> np.ndarray:
    """b'(t) / t for t >= 0 (finite at t = 0), so that grad b(1.5 |y|) = 2.25 b'(t)/t y."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(t <= 0.5, -2.0, np.where(t < 1.5, (t - 1.5) / t, 0.0))


def _monomials(y: np.ndarray) -> np.ndarray:
    """(..., 10) quadric basis x^2, y^2, z^2, xy, xz, yz, x, y, z, 1 of (..., 3) local coordinates."""
    a, b, c = y[..., 0], y[..., 1], y[..., 2]
    return np.stack([a * a, b * b, c * c, a * b, a * c, b * c, a, b, c, np.ones_like(a)], axis=-1)


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


def _normal_matrices(design: np.ndarray, weight: np.ndarray, cell: np.ndarray, cells: int) -> np.ndarray:
    """(cells, q, q) sums of weight * design_i design_j^T over the rows of each cell; ``design`` is (rows, q)."""
    upper_rows, upper_cols = np.triu_indices(design.shape[1])
    weighted = design * weight[:, None]
    upper = [np.bincount(cell, weighted[:, i] * design[:, j], minlength=cells) for i, j in zip(upper_rows, upper_cols)]
    matrices = np.empty((cells, design.shape[1], design.shape[1]))
    matrices[:, upper_rows, upper_cols] = matrices[:, upper_cols, upper_rows] = np.stack(upper, axis=1)
    return matrices


def _solve(normal: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Solutions of the stacked normal equations (minimum-norm where rank-deficient)."""
    return np.einsum("kij,kj->ki", np.linalg.pinv(normal, rcond=1e-10, hermitian=True), right)


def _fit_bivariate(y, weight, cell, axis):
    """Fit w = h(u, v), a bivariate quadratic in the frame whose w axis is ``axis`` (k, 3) per cell.

    ``y`` (rows, 3) are support points in cell coordinates, ``weight`` (rows,) and ``cell`` (rows,) their weights
    and cells.  Returns (k, 10) coefficients of f = h(u, v) - w (> 0 behind the surface, inside) in the _monomials
    basis.
    """
    helper = np.eye(3)[np.argmin(np.abs(axis), axis=1)]
    first = np.cross(axis, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = np.cross(axis, first)
    u = np.einsum("pd,pd->p", y, first[cell])
    v = np.einsum("pd,pd->p", y, second[cell])
    w = np.einsum("pd,pd->p", y, axis[cell])
    design = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=1)
    right = np.stack([np.bincount(cell, weight * w * column, minlength=len(axis)) for column in design.T], axis=1)
    h = _solve(_normal_matrices(design, weight, cell, len(axis)), right)
    # Expand h(u, v) - w with u = first . y, v = second . y into the monomials of y.
    def outer(a, b):
        return a[:, :, None] * b[:, None, :]
    form = (h[:, 0, None, None] * outer(first, first) + h[:, 2, None, None] * outer(second, second)
            + 0.5 * h[:, 1, None, None] * (outer(first, second) + outer(second, first)))
    linear = h[:, 3, None] * first + h[:, 4, None] * second - axis
    return np.column_stack([form[:, 0, 0], form[:, 1, 1], form[:, 2, 2],
                            2 * form[:, 0, 1], 2 * form[:, 0, 2], 2 * form[:, 1, 2], linear, h[:, 5]])


def _fit_general(y, weight, cell, aux_y, aux_value, aux_valid):
    """Fit a general quadric: zero on the support points (weights normalized per cell), the auxiliary values
    (averaged), as Ohtake's E = sum w_i Q(p_i)^2 / sum w_i + sum_j (Q(q_j) - d_j)^2 / m.

    ``aux_y`` (k, 9, 3), ``aux_value`` (k, 9) and ``aux_valid`` (k, 9) are the auxiliary points of each cell.
    Returns (k, 10) coefficients in the _monomials basis.
    """
    cells = len(aux_y)
    total = np.bincount(cell, weight, minlength=cells)
    aux_design = _monomials(aux_y)
    aux_weight = aux_valid / aux_valid.sum(axis=1, keepdims=True)
    normal = (_normal_matrices(_monomials(y), weight / total[cell], cell, cells)
              + np.einsum("ka,kai,kaj->kij", aux_weight, aux_design, aux_design))
    return _solve(normal, np.einsum("ka,kai->ki", aux_weight * aux_value, aux_design))


def _auxiliary_points(points, normals, tree, centres, half_side):
    """Ohtake's auxiliary points (cell corners and centre) and their signed distances (> 0 inside).

    The distance is the mean of n_j . (p_j - q) over the 6 nearest points; it is valid when all six agree in sign.
    Returns the (k, 9, 3) points, (k, 9) distances and (k, 9) validity.
    """
    where = centres[:, None, :] + _AUXILIARY * half_side
    _, near = tree.query(where.reshape(-1, 3), k=_AUX_NEIGHBOURS)
    signed = np.einsum("qjd,qjd->qj", normals[near], points[near] - where.reshape(-1, 1, 3))
    valid = (signed > 0).all(axis=1) | (signed < 0).all(axis=1)
    shape = where.shape[:2]
    return where, signed.mean(axis=1).reshape(shape), valid.reshape(shape)


def _fit_cells(points, normals, tree, centres, radii, half_side):
    """One local fit per cell: (k, 10) coefficients of f in y = (x - centre) / R, input units, and (k,) errors.

    The error of a fit is max over its support points of |f(p)| / |grad f(p)|.
    """
    supports = tree.query_ball_point(centres, radii)
    sizes = np.fromiter(map(len, supports), dtype=np.intp, count=len(supports))
    index = np.fromiter(chain.from_iterable(supports), dtype=np.intp, count=int(sizes.sum()))
    cell = np.repeat(np.arange(len(centres)), sizes)
    starts = np.r_[0, np.cumsum(sizes)[:-1]]   # every support holds min_points >= 1 points
    y = (points[index] - centres[cell]) / radii[cell, None]
    weight = _bspline(1.5 * np.linalg.norm(y, axis=1))
    axis = np.stack([np.bincount(cell, weight * column, minlength=len(centres)) for column in normals[index].T], 1)
    length = np.linalg.norm(axis, axis=1)
    cancelled = length <= 1e-9 * np.bincount(cell, weight, minlength=len(centres))
    axis[cancelled] = normals[tree.query(centres[cancelled])[1]]   # normals cancel out: take the nearest one
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    spread = np.minimum.reduceat(np.einsum("pd,pd->p", normals[index], axis[cell]), starts)

    # Normals spread over more than 90 degrees: a general quadric, where auxiliary points exist.
    general = np.flatnonzero(spread < 0)
    aux_where, aux_value, aux_valid = _auxiliary_points(points, normals, tree, centres[general], half_side)
    usable = aux_valid.any(axis=1)
    general, aux_where, aux_value, aux_valid = general[usable], aux_where[usable], aux_value[usable], aux_valid[usable]
    bivariate = np.ones(len(centres), dtype=bool)
    bivariate[general] = False

    def rows_of(chosen):
        """Mask of the support rows of the chosen cells, and their cell numbers among the chosen."""
        renumber = np.cumsum(chosen) - 1
        rows = chosen[cell]
        return rows, renumber[cell[rows]]

    coef = np.empty((len(centres), 10))
    rows, sub_cell = rows_of(~bivariate)
    aux_y = (aux_where - centres[general, None]) / radii[general, None, None]
    coef[general] = _fit_general(y[rows], weight[rows], sub_cell, aux_y, aux_value / radii[general, None], aux_valid)
    rows, sub_cell = rows_of(bivariate)
    coef[bivariate] = _fit_bivariate(y[rows], weight[rows], sub_cell, axis[bivariate])
    coef *= radii[:, None]

    value = _quadric(y.T, coef[cell].T)
    slope = np.linalg.norm(_quadric_gradient(y.T, coef[cell].T), axis=0) / radii[cell]
    return coef, np.maximum.reduceat(np.abs(value) / np.maximum(slope, 1e-300), starts)


def _support_radii(tree, centres, radius, min_points):
    """Support radius per cell: ``radius``, grown by factors 1.25 until the ball holds ``min_points`` points.

    Returns the (k,) radii and the (k,) counts in the ungrown ball.
    """
    counts = tree.query_ball_point(centres, radius, return_length=True)
    radii = np.full(len(centres), radius)
    small = counts < min_points
    if small.any():
        distance, _ = tree.query(centres[small], k=min_points)
        steps = np.ceil(np.log(distance[:, -1] * (1 + 1e-9) / radius) / np.log(_GROWTH))
        radii[small] = radius * _GROWTH ** np.maximum(steps, 0)
    return radii, counts


def fit_mpu(points, normals, *, error_bound=None, min_points: int = 15, max_depth: int = 10,
            progress: ProgressCallback = None) -> "MPUImplicit":
    """Multilevel Partition of Unity implicit (Ohtake et al. 2003) of oriented 3D points.

    An octree over the enlarged bounding cube of the points is refined while a cell's local fit misses its support
    points by more than ``error_bound``.  A cell's support is the ball of radius 0.75 x its diagonal, grown by
    factors 1.25 until it holds ``min_points`` points; a cell whose ungrown ball holds fewer is a leaf.  The local
    fit is a bivariate quadratic over the tangent plane of the weighted mean normal where all support normals are
    within 90 degrees of it, otherwise a general quadric pinned by Ohtake's auxiliary points.

    Parameters
    ----------
    points : (n, 3) float64, input units
    normals : (n, 3) float64, outward (see check_normals and estimate_normals)
    error_bound : float, input units; default 0.005 x the bounding-box diagonal
    min_points : int, points a support must hold (>= 6)
    max_depth : int, deepest octree level (root = 0)
    progress : callable(fraction, message), optional

    Returns
    -------
    MPUImplicit, f > 0 inside, about the signed distance near the surface
    """
    points = check_points(points, dims=(3,))
    if len(points) < MIN_POINTS:
        raise InvalidInputError(f"points: need at least {MIN_POINTS} points, got {len(points)}")
    normals = unit_normals(normals, points.shape)
    lower, upper, diagonal = bounding_box(points)
    error_bound = 0.005 * diagonal if error_bound is None else check_number(error_bound, "error_bound", low=0,
                                                                               low_open=True)
    min_points = min(int(check_number(min_points, "min_points", low=6)), len(points))
    max_depth = int(check_number(max_depth, "max_depth", low=0, high=20))
    tree = cKDTree(points)
    side = float(np.max(upper - lower)) * _ROOT_ENLARGEMENT
    centres = (0.5 * (lower + upper))[None]
    leaves = []
    for depth in range(max_depth + 1):
        radii, counts = _support_radii(tree, centres, _SUPPORT_FACTOR * np.sqrt(3.0) * side, min_points)
        # Batches of cells holding about _FIT_PAIRS support points, to bound the memory.
        bounds = np.flatnonzero(np.diff(np.cumsum(np.maximum(counts, min_points)) // _FIT_PAIRS)) + 1
        fits = []
        for number, (batch_centres, batch_radii) in enumerate(zip(np.split(centres, bounds), np.split(radii, bounds))):
            report(progress, (depth + number / (len(bounds) + 1)) / (max_depth + 1),
                   f"fitting MPU: level {depth}, {len(centres)} cells")
            fits.append(_fit_cells(points, normals, tree, batch_centres, batch_radii, 0.5 * side))
        coef, error = (np.concatenate(column) for column in zip(*fits))
        split = (error > error_bound) & (counts >= min_points) & (depth < max_depth)
        leaves.append((centres[~split], radii[~split], coef[~split]))
        if not split.any():
            break
        side *= 0.5
        centres = (centres[split, None, :] + 0.5 * side * _CORNERS).reshape(-1, 3)
    report(progress, 1.0, "fitting MPU: done")
    return MPUImplicit(centres=np.concatenate([leaf[0] for leaf in leaves]),
                       radii=np.concatenate([leaf[1] for leaf in leaves]),
                       coefficients=np.concatenate([leaf[2] for leaf in leaves]),
                       points=points, lower=lower, upper=upper)


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
