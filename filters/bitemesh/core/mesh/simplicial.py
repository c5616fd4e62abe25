"""The simplicial mesh every step hands on: triangles in 2D, tetrahedra in 3D, k-simplices up to 5-D."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial
from math import factorial

import numpy as np
from numba import prange

from ..compiled import kernel


#: the largest dimension of a mesh.  Not qhull's round-off: with 'QJ' it triangulated uniform points in 6-D and 7-D
#: here with no flat simplex (737 points in 6-D: 355,344 simplices in 6.1 s); but its simplices a node grow
#: with k (27, 125, 482, 866 for k = 4..7 on uniform points), so 100,000 6-simplices hold a few hundred nodes, a
#: ball a few R across: no resolution left to mesh a shape with.
MAX_DIMENSION = 5


@dataclass(frozen=True, eq=False)
class Mesh:
    """A simplicial mesh.

    Attributes
    ----------
    points : (n, k) float64, node coordinates (input units), k = 2 or 3
    cells : (m, k + 1) int64, node indices of each triangle or tetrahedron, positively oriented
    cell_data : name -> (m, ...) arrays, one row per cell; ``Region`` (m,) int32 > 0 tags the cells by region
    facets : (b, k) int64 or None, the tagged facets (triangles in 3D, edges in 2D): every boundary facet, oriented
        out of the domain, and every interface between two regions, oriented out of the region with the lower tag
    facet_tags : (b,) int32 > 0 or None, the tag of each facet
    tag_names : name -> (tag, dimension), as meshio's field_data and gmsh's physical names: dimension k for a region
        (a value of ``cell_data["Region"]``), k - 1 for a facet tag
    point_data : name -> (n, ...) arrays, one row per node (the ventricular coordinates, ...)
    unit : the unit of the points: "um", "mm", "cm" or "m" (the files that hold one say it)
    """

    points: np.ndarray
    cells: np.ndarray
    cell_data: dict = field(default_factory=dict)
    facets: np.ndarray | None = None
    facet_tags: np.ndarray | None = None
    tag_names: dict = field(default_factory=dict)
    point_data: dict = field(default_factory=dict)
    unit: str = "mm"

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    def with_cell_data(self, **arrays) -> "Mesh":
        """A copy that also holds ``arrays`` (each with one row per cell); the tags stay."""
        return replace(self, cell_data={**self.cell_data, **arrays})

    def with_point_data(self, **arrays) -> "Mesh":
        """A copy that also holds ``arrays`` (each with one row per node)."""
        return replace(self, point_data={**self.point_data, **arrays})

    def with_tags(self, facets, facet_tags, tag_names, regions=None) -> "Mesh":
        """A copy with these tagged facets (b, k), their tags (b,), the names and, if given, the cells' regions (m,)."""
        cell_data = self.cell_data if regions is None else {**self.cell_data, "Region": np.asarray(regions, np.int32)}
        return replace(self, cell_data=cell_data, facets=np.asarray(facets, np.int64),
                       facet_tags=np.asarray(facet_tags, np.int32), tag_names=dict(tag_names))


def simplex_vertices(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, k + 1, k) coordinates of the vertices of each cell."""
    return points[cells]


#: rows (cells, points) that a vectorised measure works on at once: its (block, k + 1, k[, k]) temporaries stay
#: within tens of MB (a 4-D mesh of a million cells held five such arrays of 200 MB in the radius ratio alone).
BLOCK_ROWS = 1 << 16


def by_blocks(measure, rows: np.ndarray):
    """``measure(rows)`` of a measure row by row (an array, or a tuple of arrays, over the rows), taken over blocks
    of :data:`BLOCK_ROWS` rows and joined: the same values, in bounded memory."""
    if len(rows) <= BLOCK_ROWS:
        return measure(rows)
    parts = [measure(rows[start:start + BLOCK_ROWS]) for start in range(0, len(rows), BLOCK_ROWS)]
    if isinstance(parts[0], tuple):
        return tuple(np.concatenate(part) for part in zip(*parts))
    return np.concatenate(parts)


def facet_measures(corners: np.ndarray) -> np.ndarray:
    """(f,) the (k-1)-measure of each facet (corners (f, k, k)): the length of a segment in 2-D, the area of a
    triangle, the volume of a tetrahedron in 4-D (sqrt of its edges' Gram determinant / (k - 1)!)."""
    if corners.shape[1] == 2:
        return np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1)
    if corners.shape[1] == 3:
        return 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    edges = corners[:, 1:] - corners[:, :1]
    gram = np.einsum("msi,mti->mst", edges, edges)
    return np.sqrt(np.maximum(np.linalg.det(gram), 0.0)) / factorial(edges.shape[1])


def regular_edge(measure: float, k: int) -> float:
    """The edge of the regular k-simplex of ``measure`` (its volume a^k / k! sqrt((k + 1) / 2^k)): a cell's size."""
    return float((measure * factorial(k) * np.sqrt(2.0 ** k / (k + 1))) ** (1.0 / k))


def signed_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) signed area (2D) or volume (3D) of each cell; > 0 when positively oriented."""
    return by_blocks(partial(_signed_measures, points), cells)


def _signed_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    corners = simplex_vertices(points, cells)
    edges = corners[:, 1:] - corners[:, :1]
    return np.linalg.det(edges) / factorial(points.shape[1])


def circumspheres(points: np.ndarray, cells: np.ndarray):
    """Circumcentres (m, k) and circumradii (m,) of the cells; inf for a flat cell (|det| of its edges <= 1e-300).

    Closed forms from vertex 0 with edges a, b (, c): 3D centre offset (|a|^2 b x c + |b|^2 c x a + |c|^2 a x b) /
    (2 a . (b x c)), 2D ((|a|^2 b_y - |b|^2 a_y), (|b|^2 a_x - |a|^2 b_x)) / (2 (a_x b_y - a_y b_x)).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    cells = np.ascontiguousarray(cells, dtype=np.int64).reshape(-1, points.shape[1] + 1)
    if points.shape[1] > 3:
        return by_blocks(partial(_circumspheres_any, points), cells)
    spheres = _circumspheres(points, cells)
    return spheres[:, :-1], spheres[:, -1]


def _circumspheres_any(points: np.ndarray, cells: np.ndarray):
    """:func:`circumspheres` in any dimension k: the centre's offset c from vertex 0 solves 2 E c = |e_i|^2, E the
    (k, k) edges from vertex 0 (the closed forms of 2D and 3D are Cramer's rule of it)."""
    corners = points[cells]
    edges = corners[:, 1:] - corners[:, :1]
    solvable = np.abs(np.linalg.det(edges)) > 1e-300
    offset = np.full((len(cells), points.shape[1]), np.inf)
    squared = np.einsum("mij,mij->mi", edges, edges)[solvable, :, None]
    offset[solvable] = np.linalg.solve(2.0 * edges[solvable], squared)[:, :, 0]
    radii = np.where(solvable, np.linalg.norm(np.where(solvable[:, None], offset, 0.0), axis=1), np.inf)
    return corners[:, 0] + offset, radii


@kernel
def tetrahedron_edges(points: np.ndarray, p, q, r, s):
    """The edges a, b, c of tetrahedron (p, q, r, s) from p, and b x c, c x a, a x b: six (x, y, z) tuples."""
    a0, a1, a2 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1], points[q, 2] - points[p, 2]
    b0, b1, b2 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1], points[r, 2] - points[p, 2]
    c0, c1, c2 = points[s, 0] - points[p, 0], points[s, 1] - points[p, 1], points[s, 2] - points[p, 2]
    return ((a0, a1, a2), (b0, b1, b2), (c0, c1, c2), (b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0),
            (c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0),
            (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


@kernel
def _circumsphere(points: np.ndarray, cell: np.ndarray, out: np.ndarray) -> None:
    """``out`` (k + 1,) := the circumcentre and the circumradius of one cell (k + 1,) (see :func:`circumspheres`)."""
    p, q, r = cell[0], cell[1], cell[2]
    if len(cell) == 4:
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), (bc0, bc1, bc2), (ca0, ca1, ca2), (ab0, ab1, ab2) = \
            tetrahedron_edges(points, p, q, r, cell[3])
        det = a0 * bc0 + a1 * bc1 + a2 * bc2
        aa, bb, cc = a0 * a0 + a1 * a1 + a2 * a2, b0 * b0 + b1 * b1 + b2 * b2, c0 * c0 + c1 * c1 + c2 * c2
        offset = ((aa * bc0 + bb * ca0 + cc * ab0), (aa * bc1 + bb * ca1 + cc * ab1), (aa * bc2 + bb * ca2 + cc * ab2))
    else:
        a0, a1 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1]
        b0, b1 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1]
        det = a0 * b1 - a1 * b0
        aa, bb = a0 * a0 + a1 * a1, b0 * b0 + b1 * b1
        offset = (aa * b1 - bb * a1, bb * a0 - aa * b0, 0.0)
    k = len(cell) - 1
    squared = 0.0
    for i in range(k):
        if abs(det) > 1e-300:
            out[i] = offset[i] / (2.0 * det)
            squared += out[i] * out[i]
            out[i] += points[p, i]
        else:
            out[i] = np.inf
    out[k] = np.sqrt(squared) if abs(det) > 1e-300 else np.inf


@kernel(parallel=True)
def _circumspheres(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, k + 1) :func:`_circumsphere` of every cell, on :func:`~bitemesh.core.compiled.threads` threads."""
    out = np.empty((len(cells), cells.shape[1]))
    for m in prange(len(cells)):
        _circumsphere(points, cells[m], out[m])
    return out


def facet_corners(corners: int) -> np.ndarray:
    """(corners, corners - 1) int64: facet i of a simplex (opposite vertex i) as positions in its row, ordered so
    that a positively oriented cell's facets face out of it."""
    table = np.array([[j for j in range(corners) if j != i] for i in range(corners)], dtype=np.int64)
    table[1::2, -2:] = table[1::2, :-3:-1]
    return table


def facets_of(cells: np.ndarray) -> np.ndarray:
    """(m, k + 1, k) the facets (triangles in 3D, edges in 2D) of each cell, facet i opposite vertex i.

    For a positively oriented cell each facet is ordered so that its normal points out of the cell.
    """
    return cells[:, facet_corners(cells.shape[1])]


def facet_of(cells: np.ndarray, cell: np.ndarray, opposite: np.ndarray) -> np.ndarray:
    """(p, k) the facet opposite vertex ``opposite[i]`` of cell ``cell[i]`` (both (p,)), as :func:`facets_of`
    orders it."""
    return cells[np.asarray(cell)[:, None], facet_corners(cells.shape[1])[opposite]]
