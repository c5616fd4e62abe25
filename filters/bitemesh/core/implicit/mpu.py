"""The Multilevel Partition of Unity implicit of Ohtake, Belyaev, Alexa, Turk and Seidel (SIGGRAPH 2003), section
4.1 of the paper: an octree of local quadrics (bivariate where the samples are a sheet, general with auxiliary
points elsewhere; where either is wild between two sheets that meet at a small angle, two planes joined at a sharp
edge, after the paper's piecewise fits), each cell subdivided until its fitting error is below the bound, blended by
B-spline weights.  Clamped by the depth in the data's bounding box, so that every point far from the data is
outside (f > 0 inside, about the signed distance near f = 0).

This module fits the octree (:func:`fit_mpu`); the fitted function, its evaluation and gradient, is
:class:`MPUImplicit` in :mod:`bitemesh.core.implicit.mpu_function` (re-exported here).
"""
from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from ..compiled import kernel, threads
from ..errors import InvalidInputError, check_number, check_points
from ..grid.sampled import bounding_box
from .mpu_function import MPUImplicit, _bspline_weights, _leaf_quadric, _quadric_gradient
from .normals import unit_normals
from ..progress import ProgressCallback, report

#: fewest points an implicit is fitted to.
MIN_POINTS = 10
#: the octree root is the bounding cube of the points enlarged by this factor.
_ROOT_ENLARGEMENT = 1.1
#: support radius of a cell = this x the cell diagonal; grown in steps of _GROWTH.
_SUPPORT_FACTOR = 0.75
_GROWTH = 1.25
#: data points whose normals estimate the signed distance of an auxiliary point.
_AUX_NEIGHBOURS = 6
#: a local fit is wild when it claims at an auxiliary point, with the sign that the nearest points' tangent planes
#: deny, a distance to the surface of more than this many times the distance to the nearest data point (which
#: bounds the true one; the slack covers a quadric's slope)...
_WILD_SLACK = 2.0
#: ... plus this many half cell sides (a fit's own error where an auxiliary point lies on the surface).
_WILD_TOLERANCE = 0.25
#: a cell whose support normals are not all within acos(this) = 60 degrees of their mean may be wild.
_BENT_SPREAD = 0.5
#: fewest support points of each sheet of a sharp-edge fit.
_SHEET_POINTS = 3
#: point-cell pairs assembled at once while fitting.
_FIT_PAIRS = 1 << 19

#: cell corners, then the centre, in half cell sides: Ohtake's auxiliary points.
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
_AUXILIARY = np.vstack([_CORNERS, np.zeros(3)])


def _monomials(y: np.ndarray) -> np.ndarray:
    """(..., 10) quadric basis x^2, y^2, z^2, xy, xz, yz, x, y, z, 1 of (..., 3) local coordinates."""
    a, b, c = y[..., 0], y[..., 1], y[..., 2]
    return np.stack([a * a, b * b, c * c, a * b, a * c, b * c, a, b, c, np.ones_like(a)], axis=-1)


@kernel
def _normal_matrices(design: np.ndarray, weight: np.ndarray, cell: np.ndarray, cells: int) -> np.ndarray:
    """(cells, q, q) sums of weight * design_i design_j^T over the rows of each cell; ``design`` is (rows, q).

    The rows are added in order, each term (weight design_i) design_j: the bits of one weighted ``np.bincount``
    per entry of the upper triangle, about 10x faster."""
    q = design.shape[1]
    matrices = np.zeros((cells, q, q))
    for row in range(len(cell)):
        into = matrices[cell[row]]
        for i in range(q):
            weighted = design[row, i] * weight[row]
            for j in range(i, q):
                into[i, j] += weighted * design[row, j]
    for i in range(q):
        for j in range(i + 1, q):
            matrices[:, j, i] = matrices[:, i, j]
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
    """Ohtake's auxiliary points (cell corners and centre), their signed distances (> 0 inside) and gaps.

    The distance is the mean of n_j . (p_j - q) over the 6 nearest points; it is valid when all six agree in sign.
    Returns the (k, 9, 3) points, (k, 9) distances, (k, 9) validity and (k, 9) distances to the nearest point.
    """
    where = centres[:, None, :] + _AUXILIARY * half_side
    gap, near = tree.query(where.reshape(-1, 3), k=_AUX_NEIGHBOURS, workers=threads())
    signed = np.einsum("qjd,qjd->qj", normals[near], points[near] - where.reshape(-1, 1, 3))
    valid = (signed > 0).all(axis=1) | (signed < 0).all(axis=1)
    shape = where.shape[:2]
    return where, signed.mean(axis=1).reshape(shape), valid.reshape(shape), gap[:, 0].reshape(shape)


@kernel
def _fit_errors(y: np.ndarray, coefficients: np.ndarray, second: np.ndarray, join: np.ndarray, cell: np.ndarray,
                radii: np.ndarray) -> np.ndarray:
    """(k,) max over the support rows of each cell of |f(p)| / |grad f(p)| (input units), f its local function
    (:func:`_leaf_quadric` of the (k, 10) quadrics, (k, 10) second quadrics and (k,) joins) at the (rows, 3) points
    ``y`` in cell coordinates (units of the cell's radius); a NaN stays."""
    errors = np.zeros(len(radii))
    for row in range(len(cell)):
        k = cell[row]
        a, b, z = y[row, 0], y[row, 1], y[row, 2]
        value, from_second = _leaf_quadric(a, b, z, coefficients[k], second[k], join[k])
        g0, g1, g2 = _quadric_gradient(a, b, z, second[k] if from_second else coefficients[k])
        slope = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2) / radii[k]
        error = abs(value) / max(slope, 1e-300)
        if error > errors[k] or np.isnan(error):
            errors[k] = error
    return errors


def _wildness(claims, planes, bound):
    """(...) the largest ratio of a fit's claim to its bound over the (..., 9) auxiliary points where the claim's
    sign is not the nearest points' tangent planes' (``planes``, their mean signed distance); 0 where there is none.
    Above 1: a fit that says inside (outside) where the planes say outside (inside), farther than any point allows."""
    return np.max(np.where(np.sign(claims) != np.sign(planes), np.abs(claims) / bound, 0.0), axis=-1)


def _sharp_fit(y, weight, unit_normals, aux_y, aux_value, bound, radius):
    """A fit of a sharp edge in one cell (after Ohtake's piecewise fits): the support normals in two clusters
    (weighted 2-means from the normal farthest from the mean and the normal farthest from that), the plane of each
    cluster (its weighted centroid and mean normal), joined by max where each cluster's centroid lies in front of the
    other's plane (a wedge: the union of the two half-spaces) and by min where behind (a plate or a convex edge:
    their intersection).  Planes, not quadratics: a cluster holds a few points, over which a quadratic overshoots.

    ``y`` (rows, 3) support points in cell coordinates, ``weight`` (rows,), ``unit_normals`` (rows, 3); ``aux_y``
    (9, 3) the auxiliary points, ``aux_value`` (9,) the tangent planes' distances there, ``bound`` (9,) what a fit
    may claim there (units of ``radius``, the support's).  Returns the two (10,) quadrics (planes, > 0 behind; input
    units), the join (1 or -1), the fit's :func:`_wildness` and its error (input units); None where a cluster has
    fewer than _SHEET_POINTS points (or no weight).
    """
    mean = weight @ unit_normals
    one = unit_normals[np.argmin(unit_normals @ mean)]
    other = unit_normals[np.argmin(unit_normals @ one)]
    for _ in range(8):
        in_one = unit_normals @ one >= unit_normals @ other
        if min(in_one.sum(), (~in_one).sum()) < _SHEET_POINTS or min(weight[in_one].sum(), weight[~in_one].sum()) <= 0:
            return None
        one, other = ((weight[rows] @ unit_normals[rows]) for rows in (in_one, ~in_one))
        one, other = one / np.linalg.norm(one), other / np.linalg.norm(other)
    centre_one, centre_other = (np.average(y[rows], axis=0, weights=weight[rows]) for rows in (in_one, ~in_one))
    planes = np.zeros((2, 10))
    planes[:, 6:9] = -np.stack([one, other])
    planes[:, 9] = one @ centre_one, other @ centre_other
    behind = one @ (centre_one - centre_other) + other @ (centre_other - centre_one)
    join = -1 if behind > 0 else 1
    claims = (np.maximum if join > 0 else np.minimum)(*(_monomials(aux_y) @ planes.T).T)
    planes *= radius
    error = _fit_errors(y, planes[:1], planes[1:], np.int8([join]), np.zeros(len(y), np.intp), np.array([radius]))
    return planes[0], planes[1], join, float(_wildness(claims, aux_value, bound)), float(error[0])


def _fit_cells(points, normals, tree, centres, radii, half_side, error_bound):
    """One local fit per cell: (k, 10) coefficients of f in y = (x - centre) / R, input units, (k, 10) second
    coefficients and (k,) joins of sharp-edge fits (:func:`_leaf_quadric`), and (k,) errors.

    The error of a fit is max over its support points of |f(p)| / |grad f(p)|.  A quadric that claims at
    one of its auxiliary points more than _WILD_SLACK x the distance to the nearest point (plus _WILD_TOLERANCE half
    sides), of the sign that the nearest points' tangent planes deny, is wild (:func:`_wildness`): fitted to two
    sheets that meet at a small angle (a heart's RV cavity where it meets the septum), one quadric bends between
    them (a general one about the product of their planes, a height field a steep parabola) and takes the wrong sign
    beyond their crease, where no support point shows it.  Such a cell takes a sharp-edge fit (:func:`_sharp_fit`)
    where that is less wild and misses the support points by no more (or by no more than ``error_bound``, input
    units).  Only cells whose normals spread over more than 60 degrees are asked.
    """
    supports = tree.query_ball_point(centres, radii, workers=threads())
    sizes = np.fromiter(map(len, supports), dtype=np.intp, count=len(supports))
    index = np.fromiter(chain.from_iterable(supports), dtype=np.intp, count=int(sizes.sum()))
    cell = np.repeat(np.arange(len(centres)), sizes)
    starts = np.r_[0, np.cumsum(sizes)[:-1]]   # every support holds min_points >= 1 points
    y = (points[index] - centres[cell]) / radii[cell, None]
    weight = _bspline_weights(1.5 * np.linalg.norm(y, axis=1))
    axis = np.stack([np.bincount(cell, weight * column, minlength=len(centres)) for column in normals[index].T], 1)
    length = np.linalg.norm(axis, axis=1)
    cancelled = length <= 1e-9 * np.bincount(cell, weight, minlength=len(centres))
    axis[cancelled] = normals[tree.query(centres[cancelled])[1]]   # normals cancel out: take the nearest one
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    spread = np.minimum.reduceat(np.einsum("pd,pd->p", normals[index], axis[cell]), starts)

    # Normals spread over more than 90 degrees: a general quadric, where auxiliary points exist.  Those spread over
    # more than 60 degrees may bend between two sheets: their auxiliary points tell whether they are wild.
    bent = np.flatnonzero(spread < _BENT_SPREAD)
    aux_where, aux_value, aux_valid, aux_gap = _auxiliary_points(points, normals, tree, centres[bent], half_side)
    aux_y = (aux_where - centres[bent, None]) / radii[bent, None, None]
    aux_value /= radii[bent, None]
    is_general = (spread[bent] < 0) & aux_valid.any(axis=1)
    general = np.zeros(len(centres), bool)
    general[bent[is_general]] = True

    def rows_of(chosen):
        """Mask of the support rows of the chosen cells, and their cell numbers among the chosen."""
        renumber = np.cumsum(chosen) - 1
        rows = chosen[cell]
        return rows, renumber[cell[rows]]

    coef = np.empty((len(centres), 10))
    second = np.zeros((len(centres), 10))
    join = np.zeros(len(centres), dtype=np.int8)
    rows, sub_cell = rows_of(general)
    coef[general] = _fit_general(y[rows], weight[rows], sub_cell, aux_y[is_general], aux_value[is_general],
                                 aux_valid[is_general])
    rows, sub_cell = rows_of(~general)
    coef[~general] = _fit_bivariate(y[rows], weight[rows], sub_cell, axis[~general])

    bound = (_WILD_SLACK * aux_gap + _WILD_TOLERANCE * half_side) / radii[bent, None]   # radius units
    wildness = _wildness(np.einsum("kai,ki->ka", _monomials(aux_y), coef[bent]), aux_value, bound)
    coef *= radii[:, None]
    errors = _fit_errors(y, coef, second, join, cell, radii)
    for at in np.flatnonzero(wildness > 1):
        k = bent[at]
        rows = slice(starts[k], starts[k] + sizes[k])
        sharp = _sharp_fit(y[rows], weight[rows], normals[index[rows]], aux_y[at], aux_value[at], bound[at],
                           radii[k])
        if sharp is None:
            continue
        first, other, joined, wild, error = sharp
        if wild < wildness[at] and error <= max(errors[k], error_bound):
            coef[k], second[k], join[k], errors[k] = first, other, joined, error
    return coef, second, join, errors


def _support_radii(tree, centres, radius, min_points):
    """Support radius per cell: ``radius``, grown by factors 1.25 until the ball holds ``min_points`` points.

    Returns the (k,) radii and the (k,) counts in the ungrown ball.
    """
    counts = tree.query_ball_point(centres, radius, return_length=True, workers=threads())
    radii = np.full(len(centres), radius)
    small = counts < min_points
    if small.any():
        distance, _ = tree.query(centres[small], k=min_points, workers=threads())
        steps = np.ceil(np.log(distance[:, -1] * (1 + 1e-9) / radius) / np.log(_GROWTH))
        radii[small] = radius * _GROWTH ** np.maximum(steps, 0)
    return radii, counts


def fit_mpu(points, normals, *, error_bound=None, min_points: int = 15, max_depth: int = 10,
            progress: ProgressCallback = None) -> MPUImplicit:
    """Multilevel Partition of Unity implicit (Ohtake et al. 2003) of oriented 3D points.

    An octree over the enlarged bounding cube of the points is refined while a cell's local fit misses its support
    points by more than ``error_bound``.  A cell's support is the ball of radius 0.75 x its diagonal, grown by
    factors 1.25 until it holds ``min_points`` points; a cell whose ungrown ball holds fewer is a leaf.  The local
    fit is a bivariate quadratic over the tangent plane of the weighted mean normal where all support normals are
    within 90 degrees of it, otherwise a general quadric pinned by Ohtake's auxiliary points; two planes joined at a
    sharp edge where either is wild between two sheets that meet at a small angle (:func:`_fit_cells`).

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
            fits.append(_fit_cells(points, normals, tree, batch_centres, batch_radii, 0.5 * side, error_bound))
        coef, second, join, error = (np.concatenate(column) for column in zip(*fits))
        split = (error > error_bound) & (counts >= min_points) & (depth < max_depth)
        leaves.append((centres[~split], radii[~split], coef[~split], second[~split], join[~split]))
        if not split.any():
            break
        side *= 0.5
        centres = (centres[split, None, :] + 0.5 * side * _CORNERS).reshape(-1, 3)
    report(progress, 1.0, "fitting MPU: done")
    return MPUImplicit(centres=np.concatenate([leaf[0] for leaf in leaves]),
                       radii=np.concatenate([leaf[1] for leaf in leaves]),
                       coefficients=np.concatenate([leaf[2] for leaf in leaves]),
                       second=np.concatenate([leaf[3] for leaf in leaves]),
                       join=np.concatenate([leaf[4] for leaf in leaves]),
                       points=points, lower=lower, upper=upper)
