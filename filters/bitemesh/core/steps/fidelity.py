"""Fidelity: how closely a mesh's boundary follows the samples it was made from, measured both ways.

- **samples to the boundary**: the distance of every input sample to the boundary surface (triangles; segments
  in 2D, tetrahedra in 4-D).  A mesh that lost a part of the shape, or filled a cavity, leaves samples far from its
  boundary.
- **the boundary to the samples**: the distance of every boundary facet (its centroid, weighted by its area) to
  the nearest sample.  A surface that the data does not support (a blob around outliers, a sheet from wrong
  normals) lies far from every sample, off to one side of them; a surface the data leaves a wide gap in (a scan's
  hole, a heart's base between its long-axis contours) lies far from the samples too, but they surround it.

The bounds follow from what a correct mesh can do.  Its boundary is a piecewise linear surface with edges about R
long on the zero level of f, which itself lies within the noise of the samples: a sample is within about R plus a
few noise levels of it (features smaller than R are rounded).  Between samples the boundary is at most half the
data's largest gap from them (contours on slices leave gaps of the slice spacing), plus R; beyond that, a facet still
counts as supported when the samples within twice its distance from them surround it in its tangent plane (no gap
of their directions wider than a half turn).  :func:`~.verdict.check_fidelity` refuses a mesh when more than a small
fraction of either measure exceeds its bound.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls
from scipy.spatial import cKDTree

from ..mesh.simplicial import Mesh, facet_measures
from ..mesh.topology import boundary_facets

#: a sample may be this many noise levels, plus R, from the boundary.
NOISE_LEVELS = 3.0
#: facets whose centroids are nearest to a sample are searched first, this many.
_CANDIDATES = 8
#: at most this many samples are measured against the boundary (a deterministic subsample: enough to count 0.5 %
#: of them to within a few percent); every sample is a candidate nearest sample of the boundary.
MAX_SAMPLES = 25_000


@dataclass(frozen=True)
class Fidelity:
    """How closely a mesh's boundary follows its samples (lengths in user units, shares in percent).

    Attributes
    ----------
    samples : number of samples measured against the boundary
    noise : the samples' noise level (see :func:`bitemesh.core.implicit.samples.noise_level`)
    to_boundary_mean, to_boundary_p95, to_boundary_max : distances of the samples to the boundary
    far_bound : R + 3 x noise, the distance beyond which a sample counts as far
    far_samples : percent of the samples farther than ``far_bound`` from the boundary
    from_samples_mean, from_samples_max : distances of the boundary (area-weighted mean) to the nearest sample
    support_bound : R + half the data's largest gap, the distance beyond which the boundary counts as unsupported
        unless the samples surround it
    unsupported_area : percent of the boundary's area farther than ``support_bound`` from every sample and not
        surrounded by them
    capped_area : percent of the boundary's area farther than ``support_bound`` from every sample and surrounded by
        them: openings of the samples (a scan's hole) that the mesh closes
    """

    samples: int
    noise: float
    to_boundary_mean: float
    to_boundary_p95: float
    to_boundary_max: float
    far_bound: float
    far_samples: float
    from_samples_mean: float
    from_samples_max: float
    support_bound: float
    unsupported_area: float
    capped_area: float = 0.0

    def describe(self) -> str:
        """One line for a summary: both measures and their bounds."""
        return (f"samples to boundary mean {self.to_boundary_mean:.3g}, 95% {self.to_boundary_p95:.3g}, max "
                f"{self.to_boundary_max:.3g} ({self.far_samples:.2f}% beyond {self.far_bound:.3g}); boundary to "
                f"samples mean {self.from_samples_mean:.3g}, max {self.from_samples_max:.3g} "
                f"({self.unsupported_area:.2f}% of its area beyond {self.support_bound:.3g}"
                + (f", {self.capped_area:.2f}% closing openings of the samples)" if self.capped_area else ")"))

    def scaled(self, factor: float) -> Fidelity:
        """The same measures with every length multiplied by ``factor`` (local frame -> user units)."""
        lengths = ("noise", "to_boundary_mean", "to_boundary_p95", "to_boundary_max", "far_bound",
                   "from_samples_mean", "from_samples_max", "support_bound")
        return Fidelity(**{**self.__dict__, **{name: getattr(self, name) * factor for name in lengths}})


def closest_on_facets(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(m, k) the point of each facet nearest to each point: simplices of s vertices (corners (m, s, k)): segments
    and triangles, and in 4-D and 5-D tetrahedra and 4-simplices; ``points`` (m, k) pairs with ``corners`` row by
    row.  The projection onto the facet's plane where it falls inside, else the nearest of its own facets."""
    a, b = corners[:, 0], corners[:, 1]
    if corners.shape[1] == 2:
        edge = b - a
        t = np.einsum("mi,mi->m", points - a, edge) / np.maximum(np.einsum("mi,mi->m", edge, edge), 1e-300)
        return a + np.clip(t, 0.0, 1.0)[:, None] * edge
    if corners.shape[1] == 3:
        c = corners[:, 2]
        ab, ac = b - a, c - a
        d00, d01, d11 = (np.einsum("mi,mi->m", u, v) for u, v in ((ab, ab), (ab, ac), (ac, ac)))
        ap = points - a
        d20, d21 = np.einsum("mi,mi->m", ap, ab), np.einsum("mi,mi->m", ap, ac)
        denominator = np.maximum(d00 * d11 - d01 * d01, 1e-300)
        weights = np.column_stack([(d11 * d20 - d01 * d21) / denominator, (d00 * d21 - d01 * d20) / denominator])
    else:   # the barycentric coordinates of the projection onto the facet's affine hull (pinv: a flat facet too)
        edges = corners[:, 1:] - a[:, None]
        gram = np.einsum("msi,mti->mst", edges, edges)
        weights = np.einsum("mst,mt->ms", np.linalg.pinv(gram), np.einsum("msi,mi->ms", edges, points - a))
    nearest = a + np.einsum("ms,msi->mi", weights, corners[:, 1:] - a[:, None])
    outside = np.flatnonzero(~((weights >= 0).all(axis=1) & (weights.sum(axis=1) <= 1)))
    if len(outside):   # the nearest point lies on one of the facet's own facets
        faces = [closest_on_facets(points[outside], np.delete(corners[outside], skip, axis=1))
                 for skip in range(corners.shape[1])]
        gaps = np.stack([np.linalg.norm(points[outside] - face, axis=1) for face in faces])
        nearest[outside] = np.stack(faces)[np.argmin(gaps, axis=0), np.arange(len(outside))]
    return nearest


def distances_to_facets(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n,) exact distance of each point to the nearest of the facets ``corners`` (f, k, k).

    The facets with the nearest centroids are tried first.  A facet nearer than the answer has its centroid within
    the answer plus its own radius (centroid to farthest corner): the facets up to the 99th percentile of those
    radii are then searched within that reach of the points that could still gain, and the few larger ones
    separately within theirs.
    """
    centroids = corners.mean(axis=1)
    radii = np.linalg.norm(corners - centroids[:, None], axis=2).max(axis=1)
    reach = float(np.percentile(radii, 99))
    best = np.full(len(points), np.inf)
    tree = cKDTree(centroids)
    count = min(_CANDIDATES, len(centroids))
    near_distance, near = tree.query(points, k=count)
    near_distance, near = near_distance.reshape(len(points), count), near.reshape(len(points), count)
    _nearer(points, corners, best, np.repeat(np.arange(len(points)), count), near.ravel())
    if count < len(centroids):
        unsure = np.flatnonzero(near_distance[:, -1] < best + reach)
        _nearer(points, corners, best, *_pairs(unsure, tree.query_ball_point(points[unsure], best[unsure] + reach)))
    large = np.flatnonzero(radii > reach)
    if len(large):
        found = cKDTree(centroids[large]).query_ball_point(points, best + radii[large].max())
        rows, index = _pairs(np.arange(len(points)), found)
        _nearer(points, corners, best, rows, large[index])
    return best


def _pairs(rows: np.ndarray, found) -> tuple:
    """(point rows, facet indices) of a ball query's lists, one pair per facet found."""
    counts = [len(facets) for facets in found]
    facets = np.concatenate([np.asarray(facets, dtype=np.int64) for facets in found]) if sum(counts) else \
        np.zeros(0, dtype=np.int64)
    return np.repeat(rows, counts), facets


def _nearer(points, corners, best, rows, facets) -> None:
    """Lower ``best[rows]`` to the distance of each point row to its paired facet, where nearer."""
    if len(rows):
        distance = np.linalg.norm(points[rows] - closest_on_facets(points[rows], corners[facets]), axis=1)
        np.minimum.at(best, rows, distance)


def measure_fidelity(mesh: Mesh, samples: np.ndarray, radius: float, noise: float, gap: float,
                     open_boundary=None) -> Fidelity:
    """Compare the boundary of ``mesh`` with ``samples`` both ways (see the module docstring).

    Parameters
    ----------
    mesh : a valid mesh; samples : (n, k) float64, points on the surface the data gives (same units)
    radius : R; noise : the samples' noise level; gap : the data's largest gap between samples
    open_boundary : callable (f, k) facet centroids -> (f,) bool, the facets that the method makes rather than the
        data (a base plane), left out of the boundary-to-samples measure; or None
    """
    facets = boundary_facets(mesh.cells)
    corners = mesh.points[facets]
    measured = samples[::max(1, -(-len(samples) // MAX_SAMPLES))]
    to_boundary = distances_to_facets(measured, corners)
    far_bound = radius + NOISE_LEVELS * noise
    centroids = corners.mean(axis=1)
    area = facet_measures(corners)
    if open_boundary is not None:
        area = np.where(open_boundary(centroids), 0.0, area)
    tree = cKDTree(samples)
    from_samples = tree.query(centroids)[0]
    support_bound = radius + 0.5 * gap
    far = np.flatnonzero((from_samples > support_bound) & (area > 0))
    around = surrounded(centroids[far], facet_normals(corners[far]), samples, tree, 2 * from_samples[far] + radius)
    total = max(float(area.sum()), 1e-300)
    return Fidelity(
        samples=len(measured), noise=float(noise),
        to_boundary_mean=float(to_boundary.mean()), to_boundary_p95=float(np.percentile(to_boundary, 95)),
        to_boundary_max=float(to_boundary.max()), far_bound=float(far_bound),
        far_samples=100.0 * float(np.mean(to_boundary > far_bound)),
        from_samples_mean=float((from_samples * area).sum() / total),
        from_samples_max=float(from_samples[area > 0].max(initial=0.0)), support_bound=float(support_bound),
        unsupported_area=100.0 * float(area[far[~around]].sum() / total),
        capped_area=100.0 * float(area[far[around]].sum() / total))


def facet_normals(corners: np.ndarray) -> np.ndarray:
    """(f, k) unit normals of facets (f, k, k): segments in 2D, triangles in 3D, tetrahedra in 4-D..."""
    edges = corners[:, 1:] - corners[:, :1]
    if corners.shape[1] == 2:
        normal = np.column_stack([edges[:, 0, 1], -edges[:, 0, 0]])
    elif corners.shape[1] == 3:
        normal = np.cross(edges[:, 0], edges[:, 1])
    else:   # the generalised cross product: the cofactors of the edges' matrix
        k = corners.shape[2]
        normal = np.stack([(-1) ** i * np.linalg.det(np.delete(edges, i, axis=2)) for i in range(k)], axis=1)
    return normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)


def surrounded(points: np.ndarray, normals: np.ndarray, samples: np.ndarray, tree, reach: np.ndarray) -> np.ndarray:
    """(m,) True where the samples within ``reach`` (m,) of each point surround it in the plane (line, in 2D)
    normal to its ``normals`` row: their directions leave no gap wider than a half turn."""
    result = np.zeros(len(points), bool)
    for row, near in enumerate(tree.query_ball_point(points, reach) if len(points) else []):
        offsets = samples[near] - points[row]
        offsets -= np.outer(offsets @ normals[row], normals[row])   # into the tangent plane
        if points.shape[1] == 2:
            along = offsets @ np.array([-normals[row, 1], normals[row, 0]])
            result[row] = (along > 0).any() and (along < 0).any()
        elif points.shape[1] == 3:
            first = np.cross(normals[row], [1.0, 0.0, 0.0] if abs(normals[row, 0]) < 0.9 else [0.0, 1.0, 0.0])
            angles = np.sort(np.arctan2(offsets @ np.cross(normals[row], first), offsets @ first))
            result[row] = len(angles) >= 3 and np.diff(np.r_[angles, angles[0] + 2 * np.pi]).max() < np.pi
        elif len(offsets) >= points.shape[1]:
            # beyond 3D: no half-space through the point holds every direction, i.e. the point lies inside
            # their convex hull (non-negative weights, summing to 1, that give it)
            directions = offsets / np.maximum(np.linalg.norm(offsets, axis=1, keepdims=True), 1e-300)
            system = np.vstack([directions.T, np.ones(len(directions))])
            result[row] = nnls(system, np.r_[np.zeros(points.shape[1]), 1.0])[1] < 1e-9
    return result


def on_plane(point, normal, tolerance: float):
    """The ``open_boundary`` of a domain cut by a plane: (f, k) centroids -> True within ``tolerance`` of it."""
    point, normal = np.asarray(point, dtype=np.float64), np.asarray(normal, dtype=np.float64)
    return lambda centroids: np.abs((centroids - point) @ normal) <= tolerance


def far_from(mesh: Mesh, samples: np.ndarray, bound: float) -> np.ndarray:
    """(m,) the indices of the ``samples`` (n, k) farther than ``bound`` from the boundary of ``mesh``."""
    return np.flatnonzero(distances_to_facets(samples, mesh.points[boundary_facets(mesh.cells)]) > bound)
