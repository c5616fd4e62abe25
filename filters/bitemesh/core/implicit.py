"""Scattered points -> implicit function f, section 4.1 of the paper.

Convention (the contract of :mod:`bitemesh.core.grid`): f > 0 inside, f < 0 outside, approximately the signed
distance in input units near f = 0.  Normals point outward.

Dense 3D samples use the Multilevel Partition of Unity of Ohtake, Belyaev, Alexa, Turk and Seidel (SIGGRAPH 2003);
sparse samples (2D contours) a thin-plate radial basis function.  Missing normals are estimated as in Hoppe et al.
(SIGGRAPH 1992).  Both reconstructions are clamped by the depth in the data's bounding box, so that every point
far from the data is outside.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cached_property
from itertools import chain

import numpy as np
from scipy import sparse
from scipy.interpolate import RBFInterpolator
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .errors import InvalidInputError, check_choice, check_number, check_points
from .progress import ProgressCallback, report, sub_progress

logger = logging.getLogger("bitemesh")

#: fewest points points_to_implicit accepts.
MIN_POINTS = 10
#: most points fit_rbf accepts: it solves a dense system with 3 n unknowns.
MAX_RBF_POINTS = 2000
#: neighbours compared per point by check_normals.
_CHECK_NEIGHBOURS = 6
#: a neighbour pair counts for check_normals when its edge is within 30 degrees of the tangent plane.
_TANGENT_SINE = 0.5
#: check_normals refuses normals when more than this fraction of those pairs differ by more than 120 degrees.
_CONTRADICTION_LIMIT = 0.1
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


# --- shared helpers ------------------------------------------------------------------------------------------------

def _bounding_box(points: np.ndarray):
    lower, upper = points.min(axis=0), points.max(axis=0)
    return lower, upper, float(np.linalg.norm(upper - lower))


def _box_depth(x: np.ndarray, lower: np.ndarray, upper: np.ndarray, *, gradient: bool = False):
    """Signed distance to the boundary of the box [lower, upper], > 0 inside.

    Returns the (m,) depth and, with ``gradient``, its (m, k) gradient.
    """
    beyond = x - np.clip(x, lower, upper)
    distance_out = np.linalg.norm(beyond, axis=1)
    to_faces = np.concatenate([x - lower, upper - x], axis=1)
    nearest_face = np.argmin(to_faces, axis=1)
    outside = distance_out > 0
    depth = np.where(outside, -distance_out, to_faces[np.arange(len(x)), nearest_face])
    if not gradient:
        return depth
    dim = x.shape[1]
    inward = np.zeros_like(x)
    inward[np.arange(len(x)), nearest_face % dim] = np.where(nearest_face < dim, 1.0, -1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        away = -beyond / distance_out[:, None]
    return depth, np.where(outside[:, None], away, inward)


def _check_spans_space(points: np.ndarray) -> None:
    """Refuse points that all lie in one plane (3D) or on one line (2D): they bound no volume."""
    centred = points - points.mean(axis=0)
    spread = np.linalg.eigvalsh(centred.T @ centred)
    if spread[0] <= 1e-10 * spread[-1]:
        where = "plane" if points.shape[1] == 3 else "line"
        raise InvalidInputError(
            f"points: all {len(points)} points lie in one {where}, so they enclose no "
            f"{'volume' if points.shape[1] == 3 else 'area'}; give samples of a closed surface (contour in 2D)")


def _unit_normals(normals, shape) -> np.ndarray:
    """``normals`` as unit vectors after checking their shape, finiteness and length."""
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != shape:
        raise InvalidInputError(f"normals must have the shape of points {shape}, got {normals.shape}")
    length = np.linalg.norm(normals, axis=1)
    for bad, what in ((~np.isfinite(normals).all(axis=1), "NaN or infinite"), (~(length > 0), "zero-length")):
        if bad.any():
            raise InvalidInputError(
                f"normals has {int(bad.sum())} {what} rows (first at row {int(np.argmax(bad))}); "
                f"fix them or omit normals so that they are estimated")
    return normals / length[:, None]


# --- normals -------------------------------------------------------------------------------------------------------

def estimate_normals(points, *, neighbours: int = 12) -> np.ndarray:
    """Outward unit normals of points sampled on closed surfaces (contours in 2D), after Hoppe et al. 1992.

    Each normal is the direction of least spread (PCA) of the point's ``neighbours`` nearest neighbours.  Signs are
    made consistent along the minimum spanning tree of the symmetric neighbour graph, with edge weight
    1 - |n_i . n_j| plus the sine between the edge and the tangent planes (so the tree prefers not to jump across
    thin walls).  Each connected component is seeded at its highest point (largest last coordinate) with its normal
    pointing up.  A component nested inside an odd number of others (its bounding box strictly inside theirs and
    its highest point behind their nearest normal) is a cavity wall and is flipped, so that it points into the
    cavity.

    Parameters
    ----------
    points : (n, k) float64, input units, k = 2 or 3, without duplicates
    neighbours : int, neighbours per point (>= k)

    Returns
    -------
    (n, k) float64 unit normals, pointing out of the enclosed volume (area in 2D)

    Limitations: walls (and gaps) thinner than the neighbour radius join two sheets into one component whose
    orientation is then unreliable; neighbourhoods that are all on one line (dense contours far apart) are refused.
    """
    points = check_points(points)
    count, dim = points.shape
    neighbours = int(check_number(neighbours, "neighbours", low=dim))
    if count < neighbours + 1:
        raise InvalidInputError(
            f"points: {count} points are too few to estimate normals from {neighbours} neighbours each; "
            f"give at least {neighbours + 1} points or pass normals")
    _check_spans_space(points)
    distance, near = cKDTree(points).query(points, k=neighbours + 1)
    local = points[near] - points[near].mean(axis=1, keepdims=True)
    spread, axes = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    flat = spread[:, 1] <= 1e-6 * spread[:, -1]
    if flat.any():
        raise InvalidInputError(
            f"points: the {neighbours} neighbours of {int(flat.sum())} points (first at index {int(np.argmax(flat))}) "
            f"lie on one line or coincide, so normals cannot be estimated there; pass normals, remove duplicates "
            f"or raise neighbours")
    _check_one_sheet(local, spread, axes, float(np.median(distance[:, min(3, neighbours)])))
    return _orient(points, axes[:, :, 0], near)


#: a neighbourhood holds two sheets when its points lie this far (x their spacing, RMS) off their plane, and fewer
#: than TWO_SHEET_CENTRE of them lie within half that RMS of it (one sheet with Gaussian noise: 38 %)...
TWO_SHEET_OFFSET, TWO_SHEET_CENTRE = 0.15, 0.15
#: ... and normals are refused when more than this share of the neighbourhoods do (at most 3.3 % on the sphere
#: with noise up to 0.75 of the spacing, the die, the shell, the torus, the nut, the bunny; all of a plate thinner
#: than its sample spacing).
TWO_SHEET_SHARE = 0.25


def _check_one_sheet(local: np.ndarray, spread: np.ndarray, axes: np.ndarray, spacing: float) -> None:
    """Refuse to estimate normals from neighbourhoods that straddle two sheets closer than the samples' spacing
    (a wall thinner than the sampling): their planes, and so the normals, say nothing of either sheet."""
    rms = np.sqrt(np.maximum(spread[:, 0], 0.0) / local.shape[1])
    offsets = np.abs(np.einsum("nki,ni->nk", local, axes[:, :, 0]))
    two = (rms > TWO_SHEET_OFFSET * spacing) & ((offsets < 0.5 * rms[:, None]).mean(axis=1) < TWO_SHEET_CENTRE)
    if two.mean() > TWO_SHEET_SHARE:
        raise InvalidInputError(
            f"points: {two.mean():.0%} of the points' neighbourhoods hold two sheets closer than the samples' spacing: "
            "a wall thinner than the sampling, whose normals cannot be estimated; pass normals, or sample the "
            "surface more densely than the wall is thick")


def _orient(points: np.ndarray, normals: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Flip ``normals`` consistently (see estimate_normals); ``near`` (n, k+1) are neighbour indices."""
    count, dim = points.shape
    rows = np.repeat(np.arange(count), near.shape[1])
    cols = near.ravel()
    rows, cols = rows[rows != cols], cols[rows != cols]
    edge = points[cols] - points[rows]
    edge /= np.maximum(np.linalg.norm(edge, axis=1, keepdims=True), 1e-300)   # duplicates: zero edge
    off_tangent = np.maximum(np.abs(np.einsum("ij,ij->i", normals[rows], edge)),
                             np.abs(np.einsum("ij,ij->i", normals[cols], edge)))
    weight = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + off_tangent + 1e-9
    graph = sparse.csr_matrix((weight, (rows, cols)), shape=(count, count))
    graph = graph.maximum(graph.T)
    components, label = csgraph.connected_components(graph, directed=False)

    # Seeds: the highest point of each component, pointing up.
    by_height = np.lexsort((points[:, -1], label))
    seed = by_height[np.r_[np.flatnonzero(np.diff(label[by_height])), count - 1]]

    # One tree: the spanning forest plus a virtual root (index count) joined to every seed.
    forest = csgraph.minimum_spanning_tree(graph).tocoo()
    tree = sparse.csr_matrix(
        (np.ones(forest.nnz + components), (np.r_[forest.row, np.full(components, count)], np.r_[forest.col, seed])),
        shape=(count + 1, count + 1))
    _, parent = csgraph.breadth_first_order(tree, count, directed=False, return_predecessors=True)
    parent[count] = count
    # relative[i]: the sign that makes normal i agree with its (already oriented) parent.
    extended = np.vstack([normals, np.zeros(dim)])
    relative = np.where(np.einsum("ij,ij->i", extended, extended[parent]) < 0, -1.0, 1.0)
    relative[seed] = np.where(normals[seed, -1] < 0, -1.0, 1.0)
    relative[count] = 1.0
    # Pointer jumping: sign[i] = product of the relative signs on the path to the root, in log2(depth) passes.
    sign, ancestor = relative, parent
    while (ancestor != count).any():
        sign, ancestor = sign * sign[ancestor], ancestor[ancestor]
    oriented = normals * sign[:count, None]
    return oriented * _nesting_parity(points, oriented, label, seed)[label, None]


def _nesting_parity(points, normals, label, seed) -> np.ndarray:
    """Per component, -1 if it lies inside an odd number of the other components (a cavity wall), else +1.

    Component a lies inside component b when a's bounding box lies strictly inside b's and a's seed point is
    behind the (outward) normal of its nearest point of b; the second test keeps, for example, a ball in the hole
    of a torus outside it.
    """
    components, dim = len(seed), points.shape[1]
    lower = np.full((components, dim), np.inf)
    upper = np.full((components, dim), -np.inf)
    np.minimum.at(lower, label, points)
    np.maximum.at(upper, label, points)
    boxed = ((lower[:, None] < lower[None]) & (upper[None] < upper[:, None])).all(axis=2)   # [b, a]: a in b
    members = np.split(np.argsort(label, kind="stable"), np.cumsum(np.bincount(label, minlength=components))[:-1])
    trees = {}
    enclosing = np.zeros(components, dtype=int)
    for outer, inner in zip(*np.nonzero(boxed)):
        if outer not in trees:
            trees[outer] = cKDTree(points[members[outer]])
        nearest = members[outer][trees[outer].query(points[seed[inner]])[1]]
        enclosing[inner] += normals[nearest] @ (points[seed[inner]] - points[nearest]) < 0
    return np.where(enclosing % 2 == 1, -1.0, 1.0)


def check_normals(points, normals) -> np.ndarray:
    """Validate user normals and return them as outward unit vectors.

    Normals pointing inward overall (negative flux sum_i n_i . (p_i - centroid)) are all flipped, with a warning on
    the "bitemesh" logger.  Inconsistent normals are refused: among each point's 6 nearest neighbours, only pairs
    whose edge lies within 30 degrees of the point's tangent plane are compared (neighbours across a thin wall lie
    along the normal and are skipped; across a sharp cube edge the normals differ by 90 degrees, which is allowed);
    more than 10 % of those pairs differing by more than 120 degrees (n_i . n_j < -0.5) means that the signs are
    not consistent.

    Parameters
    ----------
    points : (n, k) float64, input units
    normals : (n, k) float64, any nonzero length

    Returns
    -------
    (n, k) float64 unit normals, pointing outward
    """
    points = check_points(points)
    normals = _unit_normals(normals, points.shape)
    neighbours = min(_CHECK_NEIGHBOURS, len(points) - 1)
    if neighbours > 0:
        distance, near = cKDTree(points).query(points, k=neighbours + 1)
        distance, near = distance[:, 1:], near[:, 1:]
        edge = points[near] - points[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            sine = np.abs(np.einsum("nkd,nd->nk", edge, normals)) / distance
        tangent = sine < _TANGENT_SINE   # NaN for duplicate points: not compared
        opposed = np.einsum("nkd,nd->nk", normals[near], normals) < -0.5
        pairs = int(tangent.sum())
        if pairs and np.count_nonzero(opposed & tangent) > _CONTRADICTION_LIMIT * pairs:
            raise InvalidInputError(
                f"normals are inconsistent: {np.count_nonzero(opposed & tangent)} of {pairs} neighbouring pairs "
                f"point in opposite directions (more than {_CONTRADICTION_LIMIT:.0%}); omit normals so that "
                f"they are estimated")
    flux = float(np.einsum("nd,nd->", normals, points - points.mean(axis=0)))
    if flux < 0:
        logger.warning("normals point inward overall (flux %.3g < 0); flipped all of them to point outward", flux)
        normals = -normals
    return normals


# --- Multilevel Partition of Unity ---------------------------------------------------------------------------------

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
    normals = _unit_normals(normals, points.shape)
    lower, upper, diagonal = _bounding_box(points)
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
        box = _box_depth(x, self.lower, self.upper, gradient=gradient)
        depth, box_slope = box if gradient else (box, None)
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
        return np.minimum(self.interpolant(x), _box_depth(x, self.lower, self.upper))


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
    normals = _unit_normals(normals, points.shape)
    lower, upper, diagonal = _bounding_box(points)
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
    _check_spans_space(points[keep])
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


def grid_layout(points, grid_spacing=None, margin=None):
    """The box and spacing of the grid I that points_to_implicit samples for these points.

    Returns
    -------
    lower, upper : (k,) corners of the points' bounding box; the grid spans [lower - margin, upper + margin]
    spacing : float, grid_spacing or the bounding-box diagonal / 100
    margin : float, margin or 3 x spacing
    """
    lower, upper, diagonal = _bounding_box(points)
    spacing = diagonal / 100 if grid_spacing is None else check_number(grid_spacing, "grid_spacing", low=0,
                                                                         low_open=True)
    margin = 3 * spacing if margin is None else check_number(margin, "margin", low=0)
    return lower, upper, spacing, margin


def __getattr__(name):
    """``points_to_implicit`` lives in :mod:`bitemesh.core.pipeline` (it drops outliers and centres the points
    first); imported from here as before."""
    if name == "points_to_implicit":
        from .pipeline import points_to_implicit
        return points_to_implicit
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
