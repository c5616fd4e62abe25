"""Element quality (radius ratio, dihedral angles, edge statistics) of a simplicial mesh.  The validity checks
(:func:`check_valid_domain`, :func:`count_boundary_components`, :func:`boundary_euler_characteristic`) are
:mod:`bitemesh.core.mesh.validity`, re-exported here (``from bitemesh.core.mesh.quality import check_valid_domain``
works as before).

Dimension-generic: triangles in 2D, tetrahedra in 3D (closed forms, compiled), simplices of any dimension k by the
general formulas (:func:`radius_ratios_any`, :func:`dihedral_angles_any`).  The quality criterion is the paper's
(section 5) ``Q = k r_in / R_circ``, 1 for the regular simplex and 0 for a degenerate one.

Topology is computed exactly with integers: every facet or edge becomes an integer key of its sorted vertex
indices, and ``np.unique`` groups equal keys.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from itertools import combinations
from math import factorial

import numpy as np
from numba import prange

from ..compiled import kernel
from ..errors import InvalidInputError, check_number
from .simplicial import (Mesh, by_blocks, circumspheres, facet_corners, facets_of, signed_measures,
                         tetrahedron_edges)
from .topology import (distinct_faces)
from .validity import _check_cells, _check_mesh

#: cells a thread takes at a time in the threaded kernels; and fewer cells than this are measured on one thread
#: (a flip's few cells: a launch costs more than they do).
_BLOCK = 1024
THREADED_CELLS = 4096


def _ridge_facets(n_vertices: int) -> np.ndarray:
    """(r, 2) the two facets meeting at each (k - 2)-face of a simplex, that is the facets opposite the two
    vertices not on it; faces (edges of a tet, vertices of a triangle) in lexicographic order."""
    ridges = combinations(range(n_vertices), n_vertices - 2)
    return np.array([[j for j in range(n_vertices) if j not in ridge] for ridge in ridges])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (faster than ``np.cross`` on small trailing axes)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def facet_normals(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Outward normals of the facets of each cell, scaled by the facet's measure.

    Parameters
    ----------
    points : (n, k) float64
    cells : (m, k + 1) int, positively oriented (for negatively oriented cells the normals point inwards)

    Returns
    -------
    (m, k + 1, k) float64; row i is the normal of the facet opposite vertex i, its length the facet's area
    (3D) or length (2D).
    """
    corners = points[facets_of(cells)]  # (m, k + 1, k, k)
    first = corners[..., 1, :] - corners[..., 0, :]
    if points.shape[1] == 2:
        return np.stack([first[..., 1], -first[..., 0]], axis=-1)
    return 0.5 * cross(first, corners[..., 2, :] - corners[..., 0, :])


def radius_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Normalized radius ratio Q = k r_in / R_circ of each cell (k = 2 for triangles, 3 for tetrahedra).

    Parameters
    ----------
    points : (n, k) float64
    cells : (m, k + 1) int

    Returns
    -------
    (m,) float64 in [0, 1]: 1 for the regular simplex, 0 for a degenerate one; independent of orientation
    (:func:`signed_radius_ratio` without its sign).
    """
    return np.minimum(np.abs(signed_radius_ratio(points, cells)), 1.0)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def signed_radius_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) the radius ratio Q = k r_in / R_circ of each cell, negative for an inverted cell, 0 for a flat one.

    Closed forms.  3D, with a, b, c the edges from vertex 0 and V6 = a . (b x c) six times the volume:
    Q = 6 V6 |V6| / (S |N|), S twice the surface area, N = |a|^2 b x c + |b|^2 c x a + |c|^2 a x b
    (R_circ = |N| / 2 |V6|).  2D: Q = 4 A2 |A2| / (P l_a l_b l_c), A2 twice the signed area, P the perimeter.
    :func:`radius_ratio` is its absolute value.  ``cells`` may have more axes: (..., k + 1) gives (...).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    flat = np.ascontiguousarray(cells, dtype=np.int64).reshape(-1, points.shape[1] + 1)
    tetrahedra = _radius_ratios_3d_threads if len(flat) >= THREADED_CELLS else _radius_ratios_3d
    kernel = {2: _radius_ratios_2d, 3: tetrahedra}.get(points.shape[1], radius_ratios_any)
    return kernel(points, flat).reshape(np.shape(cells)[:-1])


def radius_ratios_any(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """:func:`signed_radius_ratio` of (m, k + 1) cells in any dimension k (the closed forms of 2D and 3D are
    specialisations of it): r_in = k |V| / (sum of the facets' measures), R_circ from :func:`circumspheres`,
    V = det(edges) / k!, a facet's measure sqrt(det(Gram matrix of its edges)) / (k - 1)!."""
    return by_blocks(partial(_radius_ratios_any, points), cells)


def _radius_ratios_any(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    k = points.shape[1]
    corners = points[cells]                                                   # (m, k + 1, k)
    volume = np.linalg.det(corners[:, 1:] - corners[:, :1]) / factorial(k)
    facets = corners[:, facet_corners(k + 1)]                                 # (m, k + 1, k, k)
    sides = facets[:, :, 1:] - facets[:, :, :1]
    gram = np.einsum("mfik,mfjk->mfij", sides, sides)
    area = np.sqrt(np.maximum(np.linalg.det(gram), 0.0)).sum(axis=1) / factorial(k - 1)
    _, radius = circumspheres(points, cells)
    ratio = np.zeros(len(cells))
    fine = (area > 0) & np.isfinite(radius) & (volume != 0)
    ratio[fine] = k * k * volume[fine] / (area[fine] * radius[fine])
    return ratio


@kernel
def _dot3(a0, a1, a2, b0, b1, b2):
    """a . b summed as numpy's einsum sums three terms: (a0 b0 + a2 b2) + a1 b1."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@kernel
def _radius_ratio_of(points, cells, m):
    """:func:`signed_radius_ratio` of tetrahedron ``m`` of ``cells``, in the order of operations of the numpy formulas
    it replaced (the same bits)."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), (bc0, bc1, bc2), (ca0, ca1, ca2), (ab0, ab1, ab2) = \
        tetrahedron_edges(points, cells[m, 0], cells[m, 1], cells[m, 2], cells[m, 3])
    six_volume = _dot3(a0, a1, a2, bc0, bc1, bc2)
    aa, bb, cc = _dot3(a0, a1, a2, a0, a1, a2), _dot3(b0, b1, b2, b0, b1, b2), _dot3(c0, c1, c2, c0, c1, c2)
    n0 = aa * bc0 + bb * ca0 + cc * ab0
    n1 = aa * bc1 + bb * ca1 + cc * ab1
    n2 = aa * bc2 + bb * ca2 + cc * ab2
    f0, f1, f2 = bc0 + ca0 + ab0, bc1 + ca1 + ab1, bc2 + ca2 + ab2  # twice the area vector opposite vertex 0
    surface = (np.sqrt(_dot3(bc0, bc1, bc2, bc0, bc1, bc2)) + np.sqrt(_dot3(ca0, ca1, ca2, ca0, ca1, ca2))
               + np.sqrt(_dot3(ab0, ab1, ab2, ab0, ab1, ab2)) + np.sqrt(_dot3(f0, f1, f2, f0, f1, f2)))
    denominator = surface * np.sqrt(_dot3(n0, n1, n2, n0, n1, n2))
    return 6.0 * six_volume * abs(six_volume) / denominator if denominator > 0 else 0.0


@kernel
def _radius_ratios_3d(points, cells):
    """:func:`signed_radius_ratio` of tetrahedra, one cell at a time on this thread (a flip's few cells)."""
    out = np.empty(len(cells))
    for m in range(len(cells)):
        out[m] = _radius_ratio_of(points, cells, m)
    return out


@kernel(parallel=True)
def _radius_ratios_3d_threads(points, cells):
    """:func:`_radius_ratios_3d` on :func:`~bitemesh.core.compiled.threads` threads (the same bits)."""
    out = np.empty(len(cells))
    for m in prange(len(cells)):
        out[m] = _radius_ratio_of(points, cells, m)
    return out


@kernel
def _radius_ratios_2d(points, cells):
    """:func:`signed_radius_ratio` of triangles (see :func:`_radius_ratios_3d`)."""
    out = np.zeros(len(cells))
    for m in range(len(cells)):
        p, q, r = cells[m, 0], cells[m, 1], cells[m, 2]
        a0, a1 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1]
        b0, b1 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1]
        twice_area = a0 * b1 - a1 * b0
        d0, d1 = b0 - a0, b1 - a1
        la, lb, lc = np.sqrt(a0 * a0 + a1 * a1), np.sqrt(b0 * b0 + b1 * b1), np.sqrt(d0 * d0 + d1 * d1)
        denominator = (la + lb + lc) * la * lb * lc
        if denominator > 0:
            out[m] = 4.0 * twice_area * abs(twice_area) / denominator
    return out


def dihedral_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Interior angle between the two facets meeting at each (k - 2)-face, in degrees.

    For tetrahedra these are the 6 dihedral angles, one per edge in the order (0,1), (0,2), (0,3), (1,2),
    (1,3), (2,3).  For triangles, the 2D equivalent: the 3 interior angles at vertices 0, 1, 2 (they sum to
    180).  NaN where a facet has zero measure (a repeated vertex); independent of orientation.

    Parameters
    ----------
    points : (n, k) float64
    cells : (m, k + 1) int

    Returns
    -------
    (m, 6) float64 for tetrahedra, (m, 3) for triangles, degrees in [0, 180].
    """
    if points.shape[1] == 3:
        return _dihedral_angles_3d(np.ascontiguousarray(points, dtype=np.float64),
                                   np.ascontiguousarray(cells, dtype=np.int64))
    if points.shape[1] > 3:
        return dihedral_angles_any(points, cells)
    normals = facet_normals(points, cells)
    pairs = _ridge_facets(cells.shape[1])
    a, b = normals[:, pairs[:, 0]], normals[:, pairs[:, 1]]
    sine = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    # interior angle = 180 - angle between outward normals; atan2 stays accurate near 0 and 180
    angles = np.degrees(np.arctan2(sine, -np.einsum("mrk,mrk->mr", a, b)))
    zero = (np.linalg.norm(a, axis=-1) == 0) | (np.linalg.norm(b, axis=-1) == 0)
    angles[zero] = np.nan
    return angles


def dihedral_angles_any(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, (k + 1) k / 2) :func:`dihedral_angles` of (m, k + 1) cells in any dimension k, degrees: facet i's
    outward normal is -grad lambda_i (lambda the barycentric coordinates: grad lambda_1..k the columns of the
    inverse of the edges from vertex 0, grad lambda_0 minus their sum), the angle at a ridge 180 minus that between
    its two facets' normals (arccos(1 / k) for the regular simplex); NaN for a flat cell."""
    return by_blocks(partial(_dihedral_angles_any, points), cells)


def _dihedral_angles_any(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    corners = points[cells]
    edges = corners[:, 1:] - corners[:, :1]
    flat = np.abs(np.linalg.det(edges)) <= 1e-300
    edges[flat] = np.eye(points.shape[1])
    gradient = np.linalg.inv(edges).transpose(0, 2, 1)                           # (m, k, k): rows grad lambda_j
    normals = -np.concatenate([-gradient.sum(axis=1, keepdims=True), gradient], axis=1)
    pairs = _ridge_facets(cells.shape[1])
    a, b = normals[:, pairs[:, 0]], normals[:, pairs[:, 1]]
    cosine = np.einsum("mrk,mrk->mr", a, b)
    sine = np.sqrt(np.maximum(np.einsum("mrk,mrk->mr", a, a) * np.einsum("mrk,mrk->mr", b, b) - cosine**2, 0.0))
    angles = np.degrees(np.arctan2(sine, -cosine))
    angles[flat] = np.nan
    return angles


#: the facets of a tetrahedron, facet i opposite vertex i, oriented out of it (as :func:`facets_of`), and the two
#: facets meeting at each edge (0,1), (0,2), (0,3), (1,2), (1,3), (2,3) (as :func:`_ridge_facets`).
_TET_FACETS = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
_TET_EDGE_FACETS = _ridge_facets(4)


@kernel(parallel=True)
def _dihedral_angles_3d(points, cells):
    """(m, 6) :func:`dihedral_angles` of tetrahedra, one cell at a time: the facets' area normals
    0.5 (q - p) x (r - p), then per edge atan2(|a x b|, -a . b) in degrees, NaN where a normal is zero; the order of
    operations of the numpy formulas it replaced (the same bits)."""
    out = np.empty((len(cells), 6))
    for block in prange((len(cells) + _BLOCK - 1) // _BLOCK):
        normal = np.empty((4, 3))
        for m in range(block * _BLOCK, min(len(cells), (block + 1) * _BLOCK)):
            _dihedral_angles_of(points, cells, m, normal, out[m])
    return out


@kernel
def _dihedral_angles_of(points, cells, m, normal, out):
    """``out`` (6,) := the dihedral angles of tetrahedron ``m``; ``normal`` (4, 3): room for its facets' normals."""
    for i in range(4):
        p, q, r = cells[m, _TET_FACETS[i, 0]], cells[m, _TET_FACETS[i, 1]], cells[m, _TET_FACETS[i, 2]]
        u0, u1, u2 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1], points[q, 2] - points[p, 2]
        v0, v1, v2 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1], points[r, 2] - points[p, 2]
        normal[i, 0] = 0.5 * (u1 * v2 - u2 * v1)
        normal[i, 1] = 0.5 * (u2 * v0 - u0 * v2)
        normal[i, 2] = 0.5 * (u0 * v1 - u1 * v0)
    for e in range(6):
        i, j = _TET_EDGE_FACETS[e, 0], _TET_EDGE_FACETS[e, 1]
        a0, a1, a2 = normal[i, 0], normal[i, 1], normal[i, 2]
        b0, b1, b2 = normal[j, 0], normal[j, 1], normal[j, 2]
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        sine = np.sqrt((c0 * c0 + c1 * c1) + c2 * c2)
        if np.sqrt((a0 * a0 + a1 * a1) + a2 * a2) == 0 or np.sqrt((b0 * b0 + b1 * b1) + b2 * b2) == 0:
            out[e] = np.nan
        else:
            out[e] = np.arctan2(sine, -_dot3(a0, a1, a2, b0, b1, b2)) * (180 / np.pi)


def edge_lengths(points: np.ndarray, cells: np.ndarray):
    """The unique edges of the mesh and their lengths.

    Parameters
    ----------
    points : (n, k) float64
    cells : (m, k + 1) int

    Returns
    -------
    edges : (e, 2) int64, vertex indices with ``edges[:, 0] < edges[:, 1]``, sorted
    lengths : (e,) float64, input units
    """
    edges = distinct_faces(_check_cells(cells), 2)
    return edges, np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)


def cell_quality(mesh: Mesh) -> dict:
    """Per-cell quality arrays, named as the VTK cell arrays of the QualityFilter.

    Returns
    -------
    dict of (m,) float64 arrays:
      ``RadiusRatio``: Q in [0, 1] (see :func:`radius_ratio`);
      ``MinDihedralAngle``, ``MaxDihedralAngle``: degrees; in 2D the smallest and largest interior angle;
      NaN for a cell with a repeated vertex;
      ``Volume``: signed volume (3D) or area (2D), input units^k, negative for an inverted cell.
    """
    points, cells = _check_mesh(mesh)
    angles = dihedral_angles(points, cells)
    return {
        "RadiusRatio": radius_ratio(points, cells),
        "MinDihedralAngle": angles.min(axis=1),
        "MaxDihedralAngle": angles.max(axis=1),
        "Volume": signed_measures(points, cells),
    }


@dataclass(frozen=True)
class QualitySummary:
    """Mesh-wide quality statistics (see :func:`quality_summary`); ``str()`` gives :func:`format_summary`.

    Angles are in degrees (dihedral in 3D, interior in 2D), lengths and volumes in input units.
    Standard deviations are population ones (ddof = 0); percentages are of all cells.
    """

    dim: int
    n_points: int
    n_cells: int
    q_mean: float
    q_std: float
    q_min: float
    q_p1: float
    q_p5: float
    q_p50: float
    percent_q_below_0_1: float
    percent_q_below_0_2: float
    percent_q_below_0_3: float
    angle_min: float
    angle_max: float
    total_volume: float
    edge_mean: float
    edge_std: float
    edge_cv: float
    edge_min: float
    edge_max: float

    def __str__(self) -> str:
        return format_summary(self)


def quality_summary(mesh: Mesh) -> QualitySummary:
    """Statistics of the radius ratio Q, of the angles, of the volume and of the edge lengths of ``mesh``.

    Raises :class:`InvalidInputError` for a mesh without cells.
    """
    points, cells = _check_mesh(mesh)
    if len(cells) == 0:
        raise InvalidInputError("mesh has no cells: there is no quality to summarise")
    arrays = cell_quality(Mesh(points, cells))
    q = arrays["RadiusRatio"]
    p1, p5, p50 = np.percentile(q, [1, 5, 50])
    min_angles, max_angles = arrays["MinDihedralAngle"], arrays["MaxDihedralAngle"]
    defined = ~np.isnan(min_angles)
    _, lengths = edge_lengths(points, cells)
    return QualitySummary(
        dim=points.shape[1],
        n_points=len(points),
        n_cells=len(cells),
        q_mean=float(q.mean()),
        q_std=float(q.std()),
        q_min=float(q.min()),
        q_p1=float(p1),
        q_p5=float(p5),
        q_p50=float(p50),
        percent_q_below_0_1=100.0 * float(np.mean(q < 0.1)),
        percent_q_below_0_2=100.0 * float(np.mean(q < 0.2)),
        percent_q_below_0_3=100.0 * float(np.mean(q < 0.3)),
        angle_min=float(min_angles[defined].min()) if defined.any() else float("nan"),
        angle_max=float(max_angles[defined].max()) if defined.any() else float("nan"),
        total_volume=float(arrays["Volume"].sum()),
        edge_mean=float(lengths.mean()),
        edge_std=float(lengths.std()),
        edge_cv=float(lengths.std() / lengths.mean()) if lengths.mean() > 0 else float("nan"),
        edge_min=float(lengths.min()),
        edge_max=float(lengths.max()),
    )


def format_summary(summary: QualitySummary) -> str:
    """A short aligned human-readable block of ``summary``, one quantity per line, for the CLI."""
    s = summary
    cells, angle, volume = {2: ("triangles", "interior angle", "area"), 3: ("tetrahedra", "dihedral angle", "volume")
                            }.get(s.dim, (f"{s.dim}-simplices", "dihedral angle", f"{s.dim}-volume"))
    lines = [
        ("mesh", f"{s.n_cells} {cells}, {s.n_points} points"),
        ("radius ratio Q", f"mean {s.q_mean:.4f}  std {s.q_std:.4f}  min {s.q_min:.4f}"),
        ("Q percentiles", f"1% {s.q_p1:.4f}  5% {s.q_p5:.4f}  50% {s.q_p50:.4f}"),
        ("cells with Q <", f"0.1: {s.percent_q_below_0_1:.2f}%  0.2: {s.percent_q_below_0_2:.2f}%  "
                           f"0.3: {s.percent_q_below_0_3:.2f}%"),
        (angle, f"min {s.angle_min:.2f} deg  max {s.angle_max:.2f} deg"),
        (volume, f"total {s.total_volume:.6g}"),
        ("edge length", f"mean {s.edge_mean:.4g}  std {s.edge_std:.4g}  cv {s.edge_cv:.3f}  "
                        f"min {s.edge_min:.4g}  max {s.edge_max:.4g}"),
    ]
    width = max(len(label) for label, _ in lines)
    return "\n".join(f"{label:<{width}}  {value}" for label, value in lines)


def quality_histogram(q: np.ndarray, bins: int = 20):
    """Histogram of radius ratios over [0, 1].

    Parameters
    ----------
    q : (m,) float64, values in [0, 1]
    bins : number of equal bins (>= 1)

    Returns
    -------
    counts : (bins,) int64
    edges : (bins + 1,) float64, from 0 to 1
    """
    if isinstance(bins, bool) or int(check_number(bins, "bins", low=1)) != bins:
        raise InvalidInputError(f"bins must be a whole number >= 1, got {bins!r}")
    counts, edges = np.histogram(np.asarray(q, dtype=np.float64), bins=int(bins), range=(0.0, 1.0))
    return counts.astype(np.int64), edges
