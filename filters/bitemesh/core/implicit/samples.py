"""What the scattered samples themselves say: outliers, spacing and noise, measured before any fit.

Outliers are found by three rules over neighbourhoods (:func:`find_outliers`), calibrated on surfaces sampled
cleanly and noisily (a sphere, a torus, the die with rounded and with sharp edges, the two-cavity shell, the
Stanford bunny scan, the nut, the biv-me guide points), none of whose points any rule flags:

- **stray groups** (:func:`stray_groups`): a group of points whose nearest neighbours are all in it, spanning less
  than :data:`STRAY_SPAN` sample spacings (a tight cluster of returns far from the object, which the far rule
  measures against itself);

- **far**: the distance to the 8th nearest neighbour is more than :data:`FAR_RATIO` times its median over the
  point's :data:`LOCAL_NEIGHBOURS` nearest (at most 2.6 times on those surfaces; 100 times or more for points
  scattered around a scene): a region sampled more sparsely than the rest is measured against itself, not
  against the dense part, and a point in the plane of its neighbours (and not off that of those that are not far
  themselves: two far points side by side tilt it through both), up to :data:`STEP_RATIO` times farther, is a
  sparser sample of their surface (the sparse side of a density step: 20 x fewer points on one half of a sphere, at
  random, put 5-16 of its points 4-5 x farther from their 8th neighbour than the dense side's median);
- **off the surface**: the distance to the plane of the 12 nearest neighbours is more than :data:`OFF_RATIO`
  times their spread along the plane (at most 0.92 on those surfaces without noise; with Gaussian noise of half
  the sample spacing, 1.37, so the bound also grows with the median of that ratio, :data:`NOISE_RATIO`).

Both run three times, so that outliers that neighbour each other are found once the others are gone.  Before
them, near-duplicates (:func:`near_duplicates`: points within :data:`DUPLICATE_SHARE` of the spacing, as scans merged
from several passes repeat them) count as one sample, so that a tight cluster of identical points (a scanner's "no
return" at the origin) is one far point, not a dense patch.  Near outliers
within about one sample spacing of the surface are not distinguishable from noise and stay; the fidelity check
(:mod:`bitemesh.core.steps.fidelity`) measures what they do to the mesh.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: a point is far when its 8th-neighbour distance exceeds this x the median 8th-neighbour distance.
FAR_RATIO = 4.0
#: a point is off the surface when its distance to its neighbours' plane exceeds this x their in-plane spread, and
#: NOISE_RATIO x the median of that ratio over the points (Gaussian noise: its largest value among 10,000 points is
#: about 5.7 x its median).
OFF_RATIO, NOISE_RATIO = 1.0, 7.0
#: a point up to STEP_RATIO x farther from its 8th neighbour than its neighbours' median is a sparser sample of their
#: surface, not a far point, when it lies nearer to their plane than IN_PLANE_RATIO x their spread along it and they
#: lie that near their plane (the sparse side of a density step, 20 x fewer points at random: 4-5.3 x farther, 0.05-0.11
#: off the plane; a point 2-3 radii off a sphere sampled 0.04 apart: more than 10 x farther).
STEP_RATIO, IN_PLANE_RATIO = 8.0, 0.25
#: neighbours of the far rule and of the plane rule, and those whose far-rule distances are a point's reference.
FAR_NEIGHBOURS, PLANE_NEIGHBOURS, LOCAL_NEIGHBOURS = 8, 12, 32
#: a group of samples apart from the rest (no point's 8 nearest neighbours outside it) spanning less than this x the
#: median distance to the 8th neighbour is no surface the sampling resolves: a scanner's stray returns.
STRAY_SPAN = 2.0
#: points nearer each other than this x the median distance to the 8th neighbour are one sample.
DUPLICATE_SHARE = 0.001
#: points nearer each other than this x the median distance to the 8th neighbour are copies of one position when
#: more than COPIED_SHARE of the points have such a copy (random sampling puts about 8 % within that of another;
#: two surfaces in contact a few): five copies of a scan, each moved by 1e-4 of its size, filled every point's 12
#: neighbours with copies of two or three positions, so the normals came out at random and the outlier rules
#: flagged a third of the points.
SAME_POSITION_SHARE, COPIED_SHARE = 0.1, 0.25
#: passes of the two rules.
PASSES = 3
#: at most this many points estimate the noise (a deterministic subsample).
NOISE_SAMPLE = 20000


def _neighbourhoods(points: np.ndarray, k: int):
    """Distances (n, k + 1) and indices of each point's k nearest neighbours (itself first)."""
    k = min(k, len(points) - 1)
    return cKDTree(points).query(points, k=k + 1)


def _planes(around: np.ndarray):
    """Least-squares planes (lines in 2D) of neighbourhoods ``around`` (n, k, d): their centres (n, d), unit
    normals (n, d), the RMS distance of the points to the plane (n,) and their RMS spread along it (n,)."""
    centre = around.mean(axis=1)
    local = around - centre[:, None]
    spread, axes = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local) / around.shape[1])
    return centre, axes[:, :, 0], np.sqrt(np.maximum(spread[:, 0], 0.0)), np.sqrt(spread[:, 1:].sum(axis=1))


def find_outliers(points: np.ndarray) -> np.ndarray:
    """(n,) bool, True for the points that the stray-group, the far or the off-surface rule flags (see the module
    docstring), copies of a scan (:func:`scan_copies`) judged once a position.

    Parameters
    ----------
    points : (n, k) float64, samples of a surface (contour in 2D), n > 13
    """
    first = scan_copies(points)
    if first is None:
        return _outliers(points)
    kept = np.flatnonzero(first == np.arange(len(points)))
    if len(kept) <= PLANE_NEIGHBOURS + 1:
        return np.zeros(len(points), bool)
    return _outliers(points[kept])[np.searchsorted(kept, first)]


def scan_copies(points: np.ndarray):
    """(n,) int64, the first of each point's copies (:func:`near_duplicates` within :data:`SAME_POSITION_SHARE`)
    when more than :data:`COPIED_SHARE` of the (n, k) points have one (scans merged a noise apart), else None."""
    first = near_duplicates(points, SAME_POSITION_SHARE)
    return first if np.mean(np.bincount(first, minlength=len(points))[first] > 1) > COPIED_SHARE else None


def _outliers(points: np.ndarray) -> np.ndarray:
    """:func:`find_outliers` of points at distinct positions."""
    outlier = stray_groups(points)
    for _ in range(PASSES):
        index = np.flatnonzero(~outlier)
        if len(index) <= PLANE_NEIGHBOURS + 1:
            break
        kept = points[index]
        distances, neighbours = _neighbourhoods(kept, LOCAL_NEIGHBOURS)   # FAR < PLANE < LOCAL neighbours
        reach = distances[:, min(FAR_NEIGHBOURS, distances.shape[1] - 1)]
        farther = reach / np.maximum(np.median(reach[neighbours[:, 1:]], axis=1), 1e-300)
        ratio, flat = _off_plane(kept, np.arange(len(kept)), neighbours[:, 1:PLANE_NEIGHBOURS + 1])
        off = ratio > max(OFF_RATIO, NOISE_RATIO * float(np.median(ratio)))
        candidate = farther > FAR_RATIO
        far = np.flatnonzero(candidate & ~off)
        far = far[~_sparser_sample(kept, far, neighbours[far, 1:], candidate, farther[far],
                                   (ratio[far] < IN_PLANE_RATIO) & flat[far])]
        flagged = index[np.union1d(far, np.flatnonzero(off))]
        if not len(flagged):
            break
        outlier[flagged] = True
    return outlier


def _off_plane(points: np.ndarray, rows: np.ndarray, around: np.ndarray):
    """(m,) the distance of the (n, k) ``points``' ``rows`` (m,) to the plane of their neighbours ``around`` (m, j)
    over the neighbours' spread along it, and (m,) bool, whether the neighbours lie near their plane (RMS distance
    below :data:`IN_PLANE_RATIO` x that spread)."""
    centre, normal, thickness, spread = _planes(points[around])
    ratio = np.abs(np.einsum("ni,ni->n", points[rows] - centre, normal)) / np.maximum(spread, 1e-300)
    return ratio, thickness < IN_PLANE_RATIO * spread


def _sparser_sample(points: np.ndarray, rows: np.ndarray, neighbours: np.ndarray, candidate: np.ndarray,
                    farther: np.ndarray, in_plane: np.ndarray) -> np.ndarray:
    """(m,) bool, which far candidates ``rows`` (m,) of ``points`` are a sparser sample of their neighbours' surface:
    at most :data:`STEP_RATIO` x farther (``farther`` (m,)), ``in_plane`` (m,) of their nearest neighbours (nearer
    their plane than :data:`IN_PLANE_RATIO` x their spread, they near it too), and not off the surface of the
    :data:`PLANE_NEIGHBOURS` nearest of ``neighbours`` (m, j) that are no far candidates (``candidate`` (n,) bool)
    themselves (:data:`OFF_RATIO`).  Two far points side by side each tilted the other's neighbours' plane through
    both; a sparse point beside a seam has sparse neighbours as far as itself, without which the plane of the seam's
    strip of dense points leans 0.25 spreads off it."""
    order = np.argsort(candidate[neighbours], axis=1, kind="stable")[:, :PLANE_NEIGHBOURS]
    off_surface = _off_plane(points, rows, np.take_along_axis(neighbours, order, axis=1))[0] > OFF_RATIO
    return (farther <= STEP_RATIO) & in_plane & ~off_surface


def stray_groups(points: np.ndarray) -> np.ndarray:
    """(n,) bool, the points of the groups that span less than :data:`STRAY_SPAN` x the median distance to the 8th
    neighbour and lie farther than :data:`FAR_RATIO` x that distance from every other point, a group being a part of
    the graph that joins each point to its 8 nearest neighbours; never every point.  (Near copies of a scan make
    small groups of that graph a spacing or two from the rest: no stray returns.)"""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    distances, neighbours = _neighbourhoods(points, FAR_NEIGHBOURS)
    rows = np.repeat(np.arange(len(points)), neighbours.shape[1])
    graph = coo_matrix((np.ones(rows.size), (rows, neighbours.ravel())), shape=(len(points),) * 2)
    count, group = connected_components(graph, directed=False)
    if count == 1:
        return np.zeros(len(points), bool)
    lower = np.full((count, points.shape[1]), np.inf)
    upper = np.full((count, points.shape[1]), -np.inf)
    np.minimum.at(lower, group, points)
    np.maximum.at(upper, group, points)
    spacing = float(np.median(distances[:, -1]))
    stray = np.linalg.norm(upper - lower, axis=1) < STRAY_SPAN * spacing
    candidates = np.flatnonzero(stray[group])
    if len(candidates):   # a small group not far from another point is part of the surface
        near = cKDTree(points).query_ball_point(points[candidates], FAR_RATIO * spacing)
        owner = np.repeat(candidates, [len(around) for around in near])
        neighbour = np.concatenate(near).astype(np.int64)
        stray[group[owner[group[neighbour] != group[owner]]]] = False
    return stray[group] if not stray.all() else np.zeros(len(points), bool)


def near_duplicates(points: np.ndarray, share: float = DUPLICATE_SHARE) -> np.ndarray:
    """(n,) int64: for each of (n, k) points the index of the first point of its group of near-duplicates (points
    within ``share`` x the median distance to the 8th neighbour, chained); itself when alone."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    distances, _ = _neighbourhoods(points, FAR_NEIGHBOURS)
    tolerance = share * float(np.median(distances[:, -1]))
    pairs = cKDTree(points).query_pairs(tolerance, output_type="ndarray")
    if not len(pairs):
        return np.arange(len(points))
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    group = connected_components(graph, directed=False)[1]
    first = np.full(group.max() + 1, len(points))
    np.minimum.at(first, group, np.arange(len(points)))
    return first[group]


def sample_spacing(points: np.ndarray) -> float:
    """The typical distance between neighbouring samples: the median distance to the k-th nearest neighbour,
    k = the dimension (input units)."""
    distances, _ = _neighbourhoods(points, points.shape[1])
    return float(np.median(distances[:, -1]))


def noise_level(points: np.ndarray) -> float:
    """The samples' noise: the median, over the points, of the RMS distance of their 12 nearest neighbours to
    those neighbours' plane (input units).  On a smooth surface sampled without noise it is the curvature's small
    sagitta; with Gaussian noise of standard deviation s it is about s."""
    step = max(1, len(points) // NOISE_SAMPLE)
    chosen = points[::step]
    _, neighbours = cKDTree(points).query(chosen, k=min(PLANE_NEIGHBOURS, len(points)))
    return float(np.median(_planes(points[neighbours])[2]))


def _to_other_slices(points: np.ndarray, slices: np.ndarray) -> np.ndarray:
    """Over every point, the distance to the nearest point on another slice; empty for fewer than two slices."""
    slices = np.asarray(slices)
    numbers = np.unique(slices)
    if len(numbers) < 2:
        return np.zeros(0)
    return np.concatenate([cKDTree(points[slices != number]).query(points[slices == number])[0]
                           for number in numbers])


def contour_gap(points: np.ndarray, slices: np.ndarray) -> float:
    """The gap contours leave between their slices: over every point, the distance to the nearest point on another
    slice; its 99th percentile (input units).  0 for fewer than two slices.

    Parameters
    ----------
    points : (n, k) float64; slices : (n,) int, the slice (contour) of each point
    """
    distances = _to_other_slices(points, slices)
    return float(np.percentile(distances, 99)) if len(distances) else 0.0


def slice_spacing(points: np.ndarray, slices: np.ndarray) -> float:
    """The typical distance between slices: the median of the distances of :func:`contour_gap` (input units)."""
    distances = _to_other_slices(points, slices)
    return float(np.median(distances)) if len(distances) else 0.0


def beyond_slices(points: np.ndarray, slices: np.ndarray):
    """For contours on parallel slices: a callable (m, k) -> (m,) bool, True beyond the first and the last slice
    (outside the slab they span), where the mesh closes the shape with caps that no contour samples; None when the
    slices are not parallel (within 10 degrees) or fewer than two."""
    normals = []
    for number in np.unique(slices):
        members = points[slices == number]
        if len(members) < 3:
            continue
        _, spread, axes = np.linalg.svd(members - members.mean(axis=0), full_matrices=False)
        if spread[-1] > 1e-3 * spread[0]:
            return None   # not planar
        normals.append(axes[-1])
    if len(normals) < 2:
        return None
    normal = normals[0]
    if np.min(np.abs(np.array(normals) @ normal)) < np.cos(np.radians(10)):
        return None
    height = points @ normal
    low, high = height.min(), height.max()
    return lambda x: (x @ normal < low) | (x @ normal > high)
