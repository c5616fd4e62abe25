"""What a source of data hands to the meshing spine: f in a local frame, and the frame back to the user's.

Scattered points (:func:`bitemesh.core.sources.points.points_source`), labelled contours
(:func:`bitemesh.core.labelled.labelled_source`) and voxels (:func:`bitemesh.labelmap.label_grid_source`) each build
a :class:`Source`; :func:`bitemesh.core.steps.spine.mesh_source` meshes it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from ..grid.sampled import ImplicitGrid
from ..mesh.simplicial import Mesh
from ..mesh.quality import cell_quality


@dataclass(frozen=True, eq=False)
class Frame:
    """The affine map from a source's local frame to the user's coordinates: ``user = local @ linear.T + shift``.

    Attributes
    ----------
    linear : (k, k) float64, invertible
    shift : (k,) float64, user units
    """

    linear: np.ndarray
    shift: np.ndarray

    @classmethod
    def identity(cls, dim: int) -> Frame:
        return cls(np.eye(dim), np.zeros(dim))

    @classmethod
    def around(cls, points: np.ndarray, *, scaled: bool = True) -> Frame:
        """The frame centred on the points' bounding box and, when ``scaled``, with their bounding-box diagonal as
        its unit: every fit, grid, Delaunay and tolerance then works on coordinates of about unit size, however far
        from the origin and however large or small the data are (coordinates of 1e7 leave qhull 1e-9 of each
        unit's precision)."""
        lower, upper = points.min(axis=0), points.max(axis=0)
        diagonal = float(np.linalg.norm(upper - lower)) if scaled else 1.0
        return cls(np.eye(points.shape[1]) * (diagonal if diagonal > 0 else 1.0), 0.5 * (lower + upper))

    @property
    def dim(self) -> int:
        return len(self.shift)

    @property
    def matrix(self) -> np.ndarray:
        """(k + 1, k + 1) the homogeneous matrix of the map."""
        matrix = np.eye(self.dim + 1)
        matrix[:-1, :-1], matrix[:-1, -1] = self.linear, self.shift
        return matrix

    @property
    def scale(self) -> float:
        """User units per local unit (the k-th root of the linear part's |determinant|)."""
        return float(abs(np.linalg.det(self.linear)) ** (1.0 / self.dim))

    @property
    def is_similarity(self) -> bool:
        """True when the map keeps angles (a rotation, a reflection or a uniform scaling, and a shift)."""
        gram = self.linear.T @ self.linear
        return bool(np.allclose(gram, self.scale**2 * np.eye(self.dim), rtol=0, atol=1e-9 * self.scale**2))

    def is_identity(self) -> bool:
        return bool(np.array_equal(self.linear, np.eye(self.dim)) and not self.shift.any())

    def to_user(self, points: np.ndarray) -> np.ndarray:
        """(n, k) local points in user coordinates."""
        return points if self.is_identity() else points @ self.linear.T + self.shift

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """(n, k) user points in local coordinates."""
        return points if self.is_identity() else np.linalg.solve(self.linear, (points - self.shift).T).T

    def grid_to_user(self, grid: ImplicitGrid) -> ImplicitGrid:
        """A grid of f in the local frame as the same grid in user coordinates and units (f scaled too); the frame
        must be a uniform scaling and a shift, as the frames of scattered points, contours and images are."""
        if not np.allclose(self.linear, self.scale * np.eye(self.dim), rtol=0, atol=1e-12 * self.scale):
            raise ValueError("grid_to_user needs a frame that is a uniform scaling and a shift, not a rotation")
        return grid.scaled(self.to_user(grid.origin[None])[0], self.scale)

    def mesh_to_user(self, mesh: Mesh) -> Mesh:
        """``mesh`` (local frame, positively oriented, quality arrays, tags) in user coordinates: a reflection swaps
        two vertices of every cell and facet back to positive (facets out of the domain), and the quality arrays are
        recomputed when angles change."""
        if self.is_identity():
            return mesh
        cells, facets = mesh.cells, mesh.facets
        if np.linalg.det(self.linear) < 0:   # a reflection turns cells and facets inside out: swap two vertices
            cells, facets = (None if rows is None else rows[:, [1, 0, *range(2, rows.shape[1])]]
                             for rows in (cells, facets))
        moved = replace(mesh, points=self.to_user(mesh.points), cells=cells, facets=facets,
                        cell_data=dict(mesh.cell_data))
        if not self.is_similarity:
            return moved.with_cell_data(**cell_quality(moved))
        factor = abs(np.linalg.det(self.linear))
        if "Volume" in moved.cell_data and not np.isclose(factor, 1.0, rtol=1e-12, atol=0):
            moved = moved.with_cell_data(Volume=moved.cell_data["Volume"] * factor)
        return moved


@dataclass(frozen=True, eq=False)
class Source:
    """What a source of data hands to :func:`mesh_source`, in its local frame.

    Attributes
    ----------
    function : callable (m, k) -> (m,), f > 0 inside, about the signed distance (local units) near f = 0
    lower, upper : (k,) float64, a box holding {f > 0} (local units); the grid I covers it and a margin
    frame : the map from the local frame to the user's coordinates
    samples : (n, k) float64, the data's points on the surface (local units), or None
    grid : f already sampled on a grid (voxels), or None; it sizes R and serves as the grid I when its spacing
        suits R (between R / 8 and R / 4), else it is resampled
    at_radius : callable R -> function, the f to mesh once R (local units) is known (labelled contours: the
        thinnest wall follows R), or None for ``function`` itself
    noise : the samples' noise level (local units); gap : the largest gap the data leaves between its samples
        (local units), e.g. the spacing of contour slices
    open_boundary : callable (f, k) points -> (f,) bool, where the boundary is made by the method rather than the
        data (a heart's base, a derived surface), or None
    notes : what the source did to the data that the user should hear of (points dropped, columns read)
    radius : R (local units) when the user gives neither radius nor cells (cells left at its default): the data's
        own element size (2 mm for cardiac contours), or None to choose R for the default cell count;
        radius_note : the sentence that says so when it is used
    handles : what SpuriousParameters.handles "auto" means for this data ("keep", or "remove" for a myocardium)
    labels : the labels meshed, for a label map
    tagging : callable (mesh, f) -> mesh, the valid mesh (local frame) with its tags, given the f that was meshed
        (:mod:`bitemesh.core.mesh.tags`), or None for one tag per boundary component
        (:func:`~bitemesh.core.mesh.tags.component_tags`)
    interfaces : regions whose interfaces the biting samples like the boundary (a label map of several labels:
        :class:`~bitemesh.core.mesh.interfaces.LabelRegions`), or None
    one_fit : f is one fit of every sample (scattered points): a handle or void at its zero level alone is a fold
        where samples cross, refused even where the mesh does not show it
        (:func:`~bitemesh.core.mesh.betti.check_topology`)
    locate : callable (indices into ``samples``) -> a sentence saying where those samples lie, with a hint that
        fits ("" when it cannot tell), for a refusal of samples far from the mesh; or None
    surface_of : callable (f, (b, k) points) -> (b,) int, which of the data's surfaces gives the meshed f at each
        point (-1: none, a heart's base), or None; a cut that removes a handle touches one of them at most (a cut
        from a cavity to the epicardium would open the cavity through its wall)
    suspects : callable () -> what in the samples may make a mesh leave them, with a hint (outliers kept on
        request, given normals that disagree with their surface), said first in a refusal of samples far from the
        mesh ("" for nothing; asked only then); or None
    """

    function: Callable[[np.ndarray], np.ndarray]
    lower: np.ndarray
    upper: np.ndarray
    frame: Frame
    samples: Optional[np.ndarray] = None
    grid: Optional[ImplicitGrid] = None
    at_radius: Optional[Callable[[float], Callable]] = None
    noise: float = 0.0
    gap: float = 0.0
    open_boundary: Optional[Callable[[np.ndarray], np.ndarray]] = None
    notes: tuple = ()
    radius: Optional[float] = None
    radius_note: str = ""
    handles: str = "keep"
    labels: tuple = ()
    tagging: Optional[Callable[[Mesh, Callable], Mesh]] = None
    interfaces: Optional[object] = None
    locate: Optional[Callable[[np.ndarray], str]] = None
    one_fit: bool = False
    suspects: Optional[Callable[[], str]] = None
    surface_of: Optional[Callable[[Callable, np.ndarray], np.ndarray]] = None

    @property
    def size(self) -> float:
        """The longest side of the box (local units)."""
        return float(np.max(np.asarray(self.upper) - np.asarray(self.lower)))

    def unsampled_on(self, grid: ImplicitGrid) -> Optional[ImplicitGrid]:
        """:attr:`open_boundary` on the nodes of ``grid`` (f sampled in user coordinates) within two spacings of
        f = 0, 1.0 where it holds and 0.0 elsewhere (the VTK chain carries it to the fidelity check); None without
        an open boundary."""
        if self.open_boundary is None:
            return None
        return self._near_surface(grid, self.open_boundary, 0.0)

    def surfaces_on(self, grid: ImplicitGrid, function) -> Optional[ImplicitGrid]:
        """:attr:`surface_of` the meshed ``function`` on the nodes of ``grid`` (f sampled in user coordinates)
        within two spacings of f = 0, -1 elsewhere (the VTK chain carries it to the handle repair); None without
        it."""
        if self.surface_of is None:
            return None
        return self._near_surface(grid, lambda x: self.surface_of(function, x), -1.0)

    def _near_surface(self, grid: ImplicitGrid, value, elsewhere: float) -> ImplicitGrid:
        """``value`` (local (m, k) points -> (m,)) on the nodes of ``grid`` within two spacings of f = 0,
        ``elsewhere`` on the others."""
        values = grid.values
        near = np.flatnonzero(np.abs(values.reshape(-1)) <= 2 * float(np.max(grid.spacing)))
        out = np.full(values.size, elsewhere)
        out[near] = value(self.frame.to_local(grid.node_coordinates(near)))
        return ImplicitGrid(origin=grid.origin, spacing=grid.spacing, values=out.reshape(values.shape))
