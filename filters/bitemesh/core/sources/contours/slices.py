"""Contour points on image slices: which slice each point was drawn on, the slices' planes, and each point's
normal in its slice (the polylines of a contour, chained into one loop, the normal pointing out of its region).

Used by :mod:`bitemesh.core.sources.contours.fit` before each surface is fitted.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from ...errors import check_number, check_points
from .surface_fit import fit_contour_rbf

#: a polyline breaks where its points are more than this x the median spacing apart.
GAP_FACTOR = 3.0
#: a contour orients itself when it is closed, or open across less than this share of its perimeter and at least this
#: round (4 pi area / perimeter^2, its area closed across the gap); other arcs take the side their neighbours show.
OPEN_SHARE, MIN_ROUNDNESS = 0.35, 0.05
#: a polyline whose ends are near is closed only when it is at least this many times longer than their distance.
CLOSED_LENGTH = 3.0
#: a slice's contour of more points than this is ordered from a nearest-neighbour graph instead of all pairs.
_DENSE_POINTS = 1500
#: infer_slices counts the points of each candidate plane among at most this many points.
_PLANE_SAMPLE = 4000


def infer_slices(points, *, tolerance=None, min_points: int = 8, seed: int = 0, trials: int = 400) -> np.ndarray:
    """Group contour points into the planes (image slices) they were drawn on, by sequential RANSAC.

    Each round samples ``trials`` triangles of nearby points (a point and two of its 30 nearest neighbours, so that
    the three are usually on one contour), takes the plane that holds the most points within ``tolerance``, refits
    it to those points by least squares and removes them.  Rounds stop when no plane holds ``min_points`` points
    that are not all on one line.  A point on the line where two slices cross goes to the larger slice.

    Parameters
    ----------
    points : (n, 3) float64, input units
    tolerance : float, input units, largest distance of a point from its plane; default 1e-3 x the bounding-box
        diagonal (contours are drawn on image planes, so their points are coplanar to rounding)
    min_points : int, fewest points a slice holds
    seed : int, seed of the sampling (the same points and seed give the same slices)

    Returns
    -------
    (n,) int64 slice ids 0, 1, ... (largest slice first); -1 for points on no plane
    """
    points = check_points(points, dims=(3,))
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    tolerance = 1e-3 * diagonal if tolerance is None else check_number(tolerance, "tolerance", low=0,
                                                                          low_open=True)
    min_points = int(check_number(min_points, "min_points", low=3))
    rng = np.random.default_rng(seed)
    slices = np.full(len(points), -1, dtype=np.int64)
    remaining = np.arange(len(points))
    for number in range(len(points)):
        if len(remaining) < min_points:
            break
        subset = points[remaining]
        k = min(30, len(subset) - 1)
        _, near = cKDTree(subset).query(subset, k=k + 1)
        first = rng.integers(0, len(subset), trials)
        second, third = near[first, rng.integers(1, k + 1, trials)], near[first, rng.integers(1, k + 1, trials)]
        a, b, c = subset[first], subset[second], subset[third]
        normal = np.cross(b - a, c - a)
        area = np.linalg.norm(normal, axis=1)
        longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - a, axis=1),
                          np.linalg.norm(c - b, axis=1)], axis=0)
        good = area > 0.05 * longest ** 2   # not a sliver: the plane is well defined
        if not good.any():
            break
        normal, a = normal[good] / area[good, None], a[good]
        sample = subset if len(subset) <= _PLANE_SAMPLE else subset[rng.choice(len(subset), _PLANE_SAMPLE, False)]
        counts = (np.abs(np.einsum("td,nd->tn", normal, sample) - np.einsum("td,td->t", normal, a)[:, None])
                  < tolerance).sum(axis=1)
        best = int(np.argmax(counts))
        inliers = np.abs((subset - a[best]) @ normal[best]) < tolerance
        for _ in range(2):   # least-squares refit on the inliers, then recount
            centre = subset[inliers].mean(axis=0)
            _, spread, axes = np.linalg.svd(subset[inliers] - centre, full_matrices=False)
            inliers = np.abs((subset - centre) @ axes[2]) < tolerance
        if inliers.sum() < min_points or spread[1] <= 1e-6 * spread[0]:
            break
        slices[remaining[inliers]] = number
        remaining = remaining[~inliers]
    return slices


@dataclass(frozen=True)
class SlicePlane:
    """A slice: its centre, unit normal and two in-plane unit axes (right-handed: axes[0] x axes[1] = normal)."""

    centre: np.ndarray
    normal: np.ndarray
    axes: np.ndarray

    def project(self, points) -> np.ndarray:
        """(m, 2) in-plane coordinates of (m, 3) points."""
        return (np.asarray(points) - self.centre) @ self.axes.T


def slice_planes(points, slices) -> dict:
    """Slice id -> :class:`SlicePlane` fitted (least squares) to the points of each slice id >= 0.

    A slice whose points lie on one line has no plane and is left out.
    """
    points = check_points(points, dims=(3,))
    slices = np.asarray(slices)
    planes = {}
    for number in np.unique(slices[slices >= 0]).tolist():
        members = points[slices == number]
        if len(members) < 3:
            continue
        centre = members.mean(axis=0)
        _, spread, axes = np.linalg.svd(members - centre, full_matrices=False)
        if spread[1] <= 1e-6 * spread[0]:
            continue
        normal = np.cross(axes[0], axes[1])
        planes[number] = SlicePlane(centre, normal / np.linalg.norm(normal), axes[:2].copy())
    return planes


# --- contours and their in-plane normals ---------------------------------------------------------------------------

def _tree_path(tree, start: int):
    """Farthest node from ``start`` along the (symmetric, weighted) tree, and the predecessor array."""
    distance, predecessors = csgraph.dijkstra(tree, directed=False, indices=start, return_predecessors=True)
    reachable = np.isfinite(distance)
    farthest = int(np.flatnonzero(reachable)[np.argmax(distance[reachable])])
    return farthest, predecessors


def polylines(q: np.ndarray, gap_factor: float):
    """Order 2D points into polylines: the longest paths of the pieces of their minimum spanning tree.

    The tree (of all pairs, or of the 16 nearest neighbours of each point when there are more than
    :data:`_DENSE_POINTS`) is cut at edges longer than ``gap_factor`` x its median edge.  Returns a list of index
    arrays (path order), the piece label of each point, and the median edge length.
    """
    count = len(q)
    if count <= _DENSE_POINTS:
        rows, cols = np.triu_indices(count, 1)
        weights = pdist(q)
    else:
        distance, near = cKDTree(q).query(q, k=17)
        rows, cols, weights = np.repeat(np.arange(count), 16), near[:, 1:].ravel(), distance[:, 1:].ravel()
    scale = float(weights.max()) if len(weights) else 1.0
    graph = sparse.csr_matrix((weights + 1e-12 * scale, (rows, cols)), shape=(count, count))   # no zero weight
    tree = csgraph.minimum_spanning_tree(graph).tocoo()
    spacing = float(np.median(tree.data)) if tree.nnz else 0.0
    keep = tree.data <= gap_factor * spacing
    forest = sparse.csr_matrix((tree.data[keep], (tree.row[keep], tree.col[keep])), shape=(count, count))
    forest = forest + forest.T
    pieces, piece = csgraph.connected_components(forest, directed=False)
    paths = []
    for number in range(pieces):
        members = np.flatnonzero(piece == number)
        if len(members) == 1:
            paths.append(members)
            continue
        a, _ = _tree_path(forest, int(members[0]))
        b, predecessors = _tree_path(forest, a)
        path = [b]
        while path[-1] != a:
            path.append(int(predecessors[path[-1]]))
        paths.append(np.array(path[::-1]))
    return paths, piece, spacing


def _signed_area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _perimeter(polygon: np.ndarray) -> float:
    return float(np.linalg.norm(polygon - np.roll(polygon, -1, axis=0), axis=1).sum())


def _inside_polygon(point: np.ndarray, polygon: np.ndarray) -> bool:
    """Even-odd rule."""
    x, y = polygon[:, 0], polygon[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    crosses = (y > point[1]) != (y2 > point[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        at = x + (point[1] - y) * (x2 - x) / (y2 - y)
    return bool(np.count_nonzero(crosses & (point[0] < at)) % 2)


def is_closed(q: np.ndarray, path: np.ndarray, spacing: float, gap_factor: float) -> bool:
    """Whether the polyline ``path`` through (m, 2) points closes on itself: its ends within ``gap_factor`` x
    ``spacing`` and its length at least :data:`CLOSED_LENGTH` x their distance (a short arc's ends are near too)."""
    gap = float(np.linalg.norm(q[path[0]] - q[path[-1]]))
    length = float(np.linalg.norm(np.diff(q[path], axis=0), axis=1).sum())
    return len(path) > 3 and gap <= gap_factor * spacing and length >= CLOSED_LENGTH * gap


def _loops(q: np.ndarray, paths, spacing: float, gap_factor: float):
    """Group polylines into closed loops: a polyline whose ends meet is a loop; the open ones are chained, nearest
    end to nearest end, into one loop (closed across the remaining gap, e.g. a valve)."""
    closed, open_ = [], []
    for path in paths:
        if len(path) < 2:
            continue
        (closed if is_closed(q, path, spacing, gap_factor) else open_).append(path)
    if open_:
        open_.sort(key=len, reverse=True)
        chain = [open_.pop(0)]
        while open_:
            end = q[chain[-1][-1]]
            starts = np.array([np.linalg.norm(q[p[0]] - end) for p in open_])
            ends = np.array([np.linalg.norm(q[p[-1]] - end) for p in open_])
            best = int(np.argmin(np.minimum(starts, ends)))
            piece = open_.pop(best)
            chain.append(piece if starts[best] <= ends[best] else piece[::-1])
        closed.append(chain)
    return [loop if isinstance(loop, list) else [loop] for loop in closed]


def _tangents(xy: np.ndarray, closed: bool, jump: float) -> np.ndarray:
    """(m, 2) tangents of a polyline, each over +/- 2 points (contours traced on the pixel grid make neighbours alone
    swing with its steps), never across a step longer than ``jump`` and 1.5 x the steps beside it (where the path
    cuts across a side branch); 0 for a point with no neighbour on its side of such steps."""
    count = len(xy)
    length = np.linalg.norm(np.diff(np.vstack([xy, xy[:1]]), axis=0), axis=1)   # step i: from i to i + 1
    if not closed:
        length[-1] = 0.0
    # a long step: longer than `jump` and than 1.5 x both steps beside it (so a change of spacing is no jump)
    beside = np.maximum(np.roll(length, 1), np.roll(length, -1))
    steps = (length > jump) & (length > 1.5 * beside)
    if closed and not steps.any():
        return np.roll(xy, -2, axis=0) - np.roll(xy, 2, axis=0)
    # open (or a loop cut after a long step, rotated to start there): segments between long steps
    start = (int(np.flatnonzero(steps)[0]) + 1) % count if closed else 0
    order = np.roll(np.arange(count), -start)
    line = xy[order]
    segment = np.r_[0, np.cumsum(steps[order][:-1])]
    index = np.arange(count)
    ahead, behind = index.copy(), index.copy()
    for shift in (1, 2):
        forward, backward = np.minimum(index + shift, count - 1), np.maximum(index - shift, 0)
        ahead = np.where(segment[forward] == segment, forward, ahead)
        behind = np.where(segment[backward] == segment, backward, behind)
    tangent = np.empty_like(xy)
    tangent[order] = line[ahead] - line[behind]
    return tangent


def _normals_2d(q: np.ndarray, gap_factor: float):
    """Outward in-plane unit normals of the points of one region in one slice: (m, 2), NaN where undefined; and
    (m,) int, -1 where the loop's own shape orients the normal, else the number of the open arc whose side the
    neighbouring contours must tell (:func:`contour_normals`)."""
    normals, unsure = np.full(q.shape, np.nan), np.full(len(q), -1)
    if len(q) < 3:
        return normals, unsure
    paths, piece, spacing = polylines(q, gap_factor)
    loops = _loops(q, paths, spacing, gap_factor)
    polygons = [q[np.concatenate(loop)] for loop in loops]
    arcs = 0
    for loop, polygon in zip(loops, polygons):
        area = _signed_area(polygon)
        perimeter = _perimeter(polygon)
        closed_loop = len(loop) == 1 and is_closed(q, loop[0], spacing, gap_factor)
        jumps = sum(np.linalg.norm(q[after[0]] - q[before[-1]]) for before, after in zip(loop, loop[1:] + loop[:1]))
        # The loop's own area orients it when it is closed, or open across a short share of its perimeter (a valve)
        # and round enough; an arc closed by its chord (a partial contour, a septum's row) may bend either way.
        sure = closed_loop or (jumps < OPEN_SHARE * perimeter
                               and 4 * np.pi * abs(area) >= MIN_ROUNDNESS * perimeter ** 2)
        # A loop inside an odd number of other loops of the region bounds a hole: its normals point into it.
        inner = sum(_inside_polygon(polygon[0], other) for other in polygons if other is not polygon) % 2
        turn = (1.0 if area >= 0 else -1.0) * (-1.0 if inner else 1.0)
        for path in loop:
            tangent = _tangents(q[path], closed_loop, 1.5 * spacing)
            length = np.linalg.norm(tangent, axis=1)
            ok = length > 0
            normals[path[ok]] = turn * np.column_stack([tangent[ok, 1], -tangent[ok, 0]]) / length[ok, None]
            if not sure:   # each arc of an unsure chain takes its own side
                unsure[path], arcs = arcs, arcs + 1
    # Points off the paths (side branches of the tree): the normal of the nearest path point of the same piece when
    # they lie beside it (a doubled row of points); a longer branch (a hook where two contours meet) gets none.
    known = np.flatnonzero(np.isfinite(normals[:, 0]))
    for number in np.unique(piece):
        members = np.flatnonzero(piece == number)
        missing = members[~np.isfinite(normals[members, 0])]
        sources = np.intersect1d(members, known)
        if len(missing) and len(sources):
            distance, nearest = cKDTree(q[sources]).query(q[missing])
            beside = distance <= 0.5 * spacing
            normals[missing[beside]] = normals[sources[nearest[beside]]]
            unsure[missing[beside]] = unsure[sources[nearest[beside]]]
    return normals, unsure


def contour_normals(points, slices, planes=None, *, gap_factor: float = GAP_FACTOR):
    """Outward in-plane unit normals of the contour points of one surface (one region).

    Per slice, the points are projected on the slice plane and ordered into polylines (the longest path of each
    piece of their minimum spanning tree, cut at edges longer than ``gap_factor`` x the median edge); the polylines
    are chained into loops (see the module docstring) and each point's normal is the in-plane perpendicular of
    its polyline, pointing out of the loop's region (out of a hole for a loop nested in another).  An open arc
    whose shape does not tell its side (a partial contour, a short or straight arc: see :data:`OPEN_SHARE`) takes
    the side the other contours give it: that of the surface fitted to them (:func:`~.surface_fit.fit_contour_rbf`,
    the arcs' points samples of f = 0); without other contours, its points keep no normal (samples of f = 0 alone).

    Parameters
    ----------
    points : (n, 3) float64, the points of one surface (a cavity, or an epicardium), input units
    slices : (n,) int, slice id per point (-1: none)
    planes : dict slice id -> SlicePlane, default fitted to these points (better: to all points of each slice)
    gap_factor : float, polyline break, x the median point spacing

    Returns
    -------
    (n, 3) float64 unit normals in the slice planes; NaN rows for points without a slice, in slices with fewer
    than 3 points of this surface, isolated, or on an arc no oriented contour tells the side of
    """
    points = check_points(points, dims=(3,))
    slices = np.asarray(slices)
    planes = slice_planes(points, slices) if planes is None else planes
    normals = np.full(points.shape, np.nan)
    arcs = np.full(len(points), -1)
    for number in np.unique(slices[slices >= 0]).tolist():
        members = np.flatnonzero(slices == number)
        plane = planes.get(number)
        if plane is None or len(members) < 3:
            continue
        in_plane, unsure = _normals_2d(plane.project(points[members]), gap_factor)
        normals[members] = in_plane @ plane.axes
        arcs[members[unsure >= 0]] = unsure[unsure >= 0] + len(points) * number   # one id per arc
    return _sided(points, normals, arcs)


def _sided(points: np.ndarray, normals: np.ndarray, arcs: np.ndarray) -> np.ndarray:
    """``normals`` with each open arc (``arcs`` >= 0: one id per arc) turned to the side where the surface fitted
    without the arcs' normals (their points samples of f = 0 alone) rises inward: the vote of the cosines between
    each arc point's normal and that fit's outward gradient; NaN where it is silent."""
    unsure = arcs >= 0
    if not unsure.any():
        return normals
    known = np.where(unsure[:, None], np.nan, normals)
    if not np.isfinite(known[:, 0]).any():
        return np.where(unsure[:, None], np.nan, normals)
    outward = -fit_contour_rbf(points, known).gradient(points[unsure])
    cosine = np.einsum("md,md->m", np.nan_to_num(normals[unsure]), outward) / np.maximum(
        np.linalg.norm(outward, axis=1), 1e-300)
    arc = np.unique(arcs[unsure], return_inverse=True)[1]
    sign = np.sign(np.bincount(arc, weights=cosine))[arc]
    result = normals.copy()
    result[unsure] *= np.where(sign != 0, sign, np.nan)[:, None]
    return result
