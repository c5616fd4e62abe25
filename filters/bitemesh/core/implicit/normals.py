"""Normals of scattered surface samples: estimated when missing (Hoppe et al., SIGGRAPH 1992: local planes
oriented consistently over a neighbour graph), checked when given (neighbours that contradict each other, several
sheets), and made unit vectors.  Normals point outward.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ..errors import InvalidInputError, check_number, check_points, point_text
from .samples import scan_copies

logger = logging.getLogger("bitemesh")

#: neighbours compared per point by check_normals.
_CHECK_NEIGHBOURS = 6
#: a neighbour pair counts for check_normals when its edge is within 30 degrees of the tangent plane.
_TANGENT_SINE = 0.5
#: ... unless each lies behind the other's normal by this sine at least: the two faces of a wall thinner than the
#: sampling, pointing away from each other.
_WALL_SINE = 0.1
#: check_normals refuses normals when more than this fraction of those pairs differ by more than 120 degrees.
_CONTRADICTION_LIMIT = 0.1


def check_spans_space(points: np.ndarray) -> None:
    """Refuse points that all lie in one plane (3D) or on one line (2D): they bound no volume."""
    centred = points - points.mean(axis=0)
    spread = np.linalg.eigvalsh(centred.T @ centred)
    if spread[0] <= 1e-10 * spread[-1]:
        where = "plane" if points.shape[1] == 3 else "line"
        raise InvalidInputError(
            f"points: all {len(points)} points lie in one {where}, so they enclose no "
            f"{'volume' if points.shape[1] == 3 else 'area'}; give samples of a closed surface (contour in 2D"
            + (": a 2D contour in a table of x y z reads as 2D with --columns x,y,skip, or x,skip,z, or skip,y,z"
               if points.shape[1] == 3 else "") + ")")


#: given normals disagree with their surface when more than this share point against the estimated ones (and
#: less than 1 - it: all of them inward, check_normals turns them round).
DISAGREEING_SHARE = 0.05


def disagreeing_normals(points, normals) -> str:
    """A sentence naming given ``normals`` (n, k) that point against the normals estimated from the (n, k) points
    (:func:`estimate_normals`) on more than :data:`DISAGREEING_SHARE` of them, where, and the hint; "" when they
    agree (or cannot be compared)."""
    try:
        estimated = estimate_normals(points)
    except InvalidInputError:
        return ""
    against = np.einsum("ij,ij->i", np.asarray(normals, dtype=np.float64), estimated) < 0
    if not DISAGREEING_SHARE < against.mean() < 1 - DISAGREEING_SHARE:
        return ""
    centre = point_text(points[against].mean(axis=0))
    columns = ",".join(["x", "y", "z"][:points.shape[1]] + ["skip"] * points.shape[1])
    return (f"{against.mean():.0%} of the given normals point against the surface their points sample (those "
            f"around {centre}): normals flipped on part of the surface; fix them, or leave them out (--columns "
            f"{columns} for a table of points and normals) to have them estimated")


def unit_normals(normals, shape) -> np.ndarray:
    """``normals`` as unit vectors after checking their shape, finiteness and length."""
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != shape:
        raise InvalidInputError(f"normals must have the shape of points {shape}, got {normals.shape}")
    length = np.linalg.norm(normals, axis=1)
    for bad, what in ((~np.isfinite(normals).all(axis=1), "NaN or infinite"), (~(length > 0), "zero-length")):
        if bad.any():
            raise InvalidInputError(
                f"normals has {int(bad.sum())} {what} rows (first at row {int(np.argmax(bad))}); "
                f"fix them or omit normals so that they are estimated (in a table of x y z nx ny nz: --columns "
                "x,y,z,skip,skip,skip)")
    return normals / length[:, None]


def estimate_normals(points, *, neighbours: int = 12) -> np.ndarray:
    """Outward unit normals of points sampled on closed surfaces (contours in 2D), after Hoppe et al. 1992.

    Each normal is the direction of least spread (PCA) of the point's ``neighbours`` nearest neighbours.  Signs are
    made consistent along the minimum spanning tree of the symmetric neighbour graph, with edge weight
    1 - |n_i . n_j| plus the sine between the edge and the tangent planes (so the tree prefers not to jump across
    thin walls).  The tree is seeded at every vertex of the points' convex hull whose normal lies along its hull
    normal, pointing out of the hull (two surfaces in contact each take their signs from their own part of the
    hull, not across the contact), and a component with no such vertex at its highest point (largest last
    coordinate), pointing up.  Such a component nested inside an odd number of others (its bounding box strictly
    inside theirs and its highest point behind their nearest normal) is a cavity wall and is flipped, so that it
    points into the cavity.

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
    check_spans_space(points)
    first = scan_copies(points)
    if first is None:
        return _estimated(points, neighbours)
    kept = np.flatnonzero(first == np.arange(count))   # copies of a scan: one normal a position
    if len(kept) < neighbours + 1:
        raise InvalidInputError(
            f"points: {len(kept)} distinct positions (of {count} points) are too few to estimate normals from "
            f"{neighbours} neighbours each; give at least {neighbours + 1} or pass normals")
    return _estimated(points[kept], neighbours)[np.searchsorted(kept, first)]


def _estimated(points: np.ndarray, neighbours: int) -> np.ndarray:
    """:func:`estimate_normals` of checked points, each its own neighbourhood's."""
    distance, near = cKDTree(points).query(points, k=neighbours + 1)
    local = points[near] - points[near].mean(axis=1, keepdims=True)
    spread, axes = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    flat = spread[:, 1] <= 1e-6 * spread[:, -1]
    if flat.any():
        raise InvalidInputError(
            f"points: the {neighbours} neighbours of {int(flat.sum())} points (first at index {int(np.argmax(flat))}) "
            f"lie on one line or coincide, so normals cannot be estimated there; pass normals, remove duplicates "
            f"or raise neighbours")
    spacing = float(np.median(distance[:, min(3, neighbours)]))
    _check_one_sheet(local, spread, axes, spacing)
    return _orient(points, axes[:, :, 0], near, spacing)


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


def _orient(points: np.ndarray, normals: np.ndarray, near: np.ndarray, spacing: float) -> np.ndarray:
    """Flip ``normals`` consistently (see estimate_normals); ``near`` (n, k+1) are neighbour indices, ``spacing``
    the samples' (input units)."""
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

    # Seeds: the hull's vertices and the slabs' outermost points whose normal clearly points out of or into the hull
    # (the slab), and the highest point of each component that has none, pointing up.
    hull_seed, hull_sign = (np.r_[first, second] for first, second in zip(_hull_seeds(points, normals),
                                                                         _slab_seeds(points, normals, spacing)))
    by_height = np.lexsort((points[:, -1], label))
    highest = by_height[np.r_[np.flatnonzero(np.diff(label[by_height])), count - 1]]   # one per component
    top = highest[~np.isin(np.arange(components), label[hull_seed])]
    seed = np.r_[hull_seed, top]
    seed_sign = np.r_[hull_sign, np.where(normals[top, -1] < 0, -1.0, 1.0)]

    # One tree: the minimum spanning tree of the graph with a virtual root (index count) joined to every seed at
    # no cost, so that each point hangs from one seed by a path along its surface.
    root_edges = sparse.csr_matrix((np.full(len(seed), 1e-12), (np.full(len(seed), count), seed)),
                                   shape=(count + 1, count + 1))
    tree = csgraph.minimum_spanning_tree(sparse.block_diag([graph, sparse.csr_matrix((1, 1))]).tocsr() + root_edges)
    _, parent = csgraph.breadth_first_order(tree, count, directed=False, return_predecessors=True)
    parent[count] = count
    # relative[i]: the sign that makes normal i agree with its (already oriented) parent.
    extended = np.vstack([normals, np.zeros(dim)])
    relative = np.where(np.einsum("ij,ij->i", extended, extended[parent]) < 0, -1.0, 1.0)
    relative[seed] = seed_sign
    relative[count] = 1.0
    # Pointer jumping: sign[i] = product of the relative signs on the path to the root, in log2(depth) passes.
    sign, ancestor = relative, parent
    while (ancestor != count).any():
        sign, ancestor = sign * sign[ancestor], ancestor[ancestor]
    oriented = normals * sign[:count, None]
    parity = _nesting_parity(points, oriented, label, highest)
    parity[label[hull_seed]] = 1.0   # a component on the hull lies inside no other
    return oriented * parity[label, None]


#: a hull vertex seeds the orientation when its normal lies within 30 degrees of its hull normal (or the opposite).
_HULL_SEED_COSINE = np.cos(np.radians(30))


def _hull_seeds(points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices of the points' convex hull whose normal is clearly along their hull normal, and the signs that make
    those normals point out of the hull: (m,) indices, (m,) +-1.  Every closed surface touching the hull is seeded
    there, so that surfaces that touch (two objects in contact) do not take their signs from each other."""
    try:
        hull = ConvexHull(points, qhull_options="QbB")
    except QhullError:
        return np.zeros(0, dtype=int), np.zeros(0)
    outward = np.zeros_like(points)
    np.add.at(outward, hull.simplices.ravel(), np.repeat(hull.equations[:, :-1], points.shape[1], axis=0))
    vertex = hull.vertices
    cosine = np.einsum("ij,ij->i", normals[vertex], outward[vertex]) / np.linalg.norm(outward[vertex], axis=1)
    clear = np.abs(cosine) > _HULL_SEED_COSINE
    return vertex[clear], np.where(cosine[clear] < 0, -1.0, 1.0)


#: the slabs of _slab_seeds are this many sample spacings thick.
_SLAB_SPACINGS = 4.0


def _slab_seeds(points: np.ndarray, normals: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """The outermost points of slabs :data:`_SLAB_SPACINGS` spacings thick across each axis, in each direction
    along the other axes, whose normal is clearly along that direction, and the signs that make those normals point
    it: (m,) indices, (m,) +-1.  Nothing lies beyond such a point in its slab, so its surface faces out there: a
    surface with no vertex of the hull (the middle one of three objects in a row, touching) is seeded too."""
    seeds, signs = [], []
    for axis in range(points.shape[1]):
        slab = np.floor((points[:, axis] - points[:, axis].min()) / (_SLAB_SPACINGS * spacing)).astype(np.int64)
        for other in set(range(points.shape[1])) - {axis}:
            for direction in (1.0, -1.0):
                order = np.lexsort((-direction * points[:, other], slab))
                outermost = order[np.r_[0, np.flatnonzero(np.diff(slab[order])) + 1]]
                cosine = direction * normals[outermost, other]
                clear = np.abs(cosine) > _HULL_SEED_COSINE
                seeds.append(outermost[clear])
                signs.append(np.where(cosine[clear] < 0, -1.0, 1.0))
    return np.concatenate(seeds), np.concatenate(signs)


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
    along the normal and are skipped, and so are two that each lie behind the other's normal: the faces of a wall
    thinner than the sampling; across a sharp cube edge the normals differ by 90 degrees, which is allowed);
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
    normals = unit_normals(normals, points.shape)
    neighbours = min(_CHECK_NEIGHBOURS, len(points) - 1)
    if neighbours > 0:
        distance, near = cKDTree(points).query(points, k=neighbours + 1)
        distance, near = distance[:, 1:], near[:, 1:]
        edge = points[near] - points[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            along = np.einsum("nkd,nd->nk", edge, normals)
            sine = np.abs(along) / distance
        tangent = sine < _TANGENT_SINE   # NaN for duplicate points: not compared
        # opposed, unless each lies behind the other's normal: the two faces of a thin wall
        facing_away = (along < -_WALL_SINE * distance) & (np.einsum("nkd,nkd->nk", edge, normals[near]) >
                                                           _WALL_SINE * distance)
        opposed = (np.einsum("nkd,nd->nk", normals[near], normals) < -0.5) & ~facing_away
        pairs = int(tangent.sum())
        if pairs and np.count_nonzero(opposed & tangent) > _CONTRADICTION_LIMIT * pairs:
            raise InvalidInputError(
                f"normals are inconsistent: {np.count_nonzero(opposed & tangent)} of {pairs} neighbouring pairs "
                f"point in opposite directions (more than {_CONTRADICTION_LIMIT:.0%}); omit normals so that "
                "they are estimated (in a table of x y z nx ny nz: --columns x,y,z,skip,skip,skip)")
    flux = float(np.einsum("nd,nd->", normals, points - points.mean(axis=0)))
    if flux < 0:
        logger.warning("normals point inward overall (flux %.3g < 0); flipped all of them to point outward", flux)
        normals = -normals
    return normals
