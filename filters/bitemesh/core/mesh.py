"""The simplicial mesh every step hands on: triangles in 2D, tetrahedra in 3D."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import factorial

import numpy as np


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
    """

    points: np.ndarray
    cells: np.ndarray
    cell_data: dict = field(default_factory=dict)
    facets: np.ndarray | None = None
    facet_tags: np.ndarray | None = None
    tag_names: dict = field(default_factory=dict)

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    def with_cell_data(self, **arrays) -> "Mesh":
        """A copy that also holds ``arrays`` (each with one row per cell); the tags stay."""
        return replace(self, cell_data={**self.cell_data, **arrays})

    def with_tags(self, facets, facet_tags, tag_names, regions=None) -> "Mesh":
        """A copy with these tagged facets (b, k), their tags (b,), the names and, if given, the cells' regions (m,)."""
        cell_data = self.cell_data if regions is None else {**self.cell_data, "Region": np.asarray(regions, np.int32)}
        return replace(self, cell_data=cell_data, facets=np.asarray(facets, np.int64),
                       facet_tags=np.asarray(facet_tags, np.int32), tag_names=dict(tag_names))


def simplex_vertices(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, k + 1, k) coordinates of the vertices of each cell."""
    return points[cells]


def signed_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) signed area (2D) or volume (3D) of each cell; > 0 when positively oriented."""
    corners = simplex_vertices(points, cells)
    edges = corners[:, 1:] - corners[:, :1]
    return np.linalg.det(edges) / factorial(points.shape[1])


def circumspheres(points: np.ndarray, cells: np.ndarray):
    """Circumcentres (m, k) and circumradii (m,) of the cells; inf/nan-free only for non-degenerate cells.

    Solves 2 (v_i - v_0) . (c - v_0) = |v_i - v_0|^2 for i = 1..k, cell by cell, vectorized.
    """
    corners = simplex_vertices(points, cells)
    edges = corners[:, 1:] - corners[:, :1]
    rhs = np.einsum("mij,mij->mi", edges, edges)
    with np.errstate(all="ignore"):
        det = np.linalg.det(edges)
        safe = np.abs(det) > 1e-300
        offset = np.full(edges.shape[:2], np.inf)
        offset[safe] = np.linalg.solve(2.0 * edges[safe], rhs[safe][..., None])[..., 0]
    return corners[:, 0] + offset, np.linalg.norm(offset, axis=1)


def facets_of(cells: np.ndarray) -> np.ndarray:
    """(m, k + 1, k) the facets (triangles in 3D, edges in 2D) of each cell, facet i opposite vertex i.

    For a positively oriented cell each facet is ordered so that its normal points out of the cell.
    """
    facets = np.stack([np.delete(cells, i, axis=1) for i in range(cells.shape[1])], axis=1)
    facets[:, 1::2, -2:] = facets[:, 1::2, :-3:-1]
    return facets
