"""Regions of a mesh of several labels (a label map): each cell in the label whose f is largest at its centroid,
and the interfaces between regions sampled and snapped like the boundary.

The mesh is the union's (one biting, one Delaunay, one valid domain), so the regions conform: the interface
facets are facets of both regions' cells, and the regions share their nodes.  Cut along centroids alone, the
interface would be a staircase of cell facets, up to about a cell from the true one (where f_a = f_b).  So:

1. the biting treats the interface as it treats the boundary (:meth:`LabelRegions.node_regions`,
   :meth:`LabelRegions.onto_interfaces`): the grid nodes next to a node of another region are bitten first and
   their nodes go onto f_a = f_b;
2. after the MeshOptimizer (which relaxes those nodes as interior ones), :func:`snap_interfaces` moves each node
   that lies on one interface only, and not on the boundary, back onto f_a = f_b by Newton steps along
   grad (f_a - f_b), and each node on one interface and the boundary along the boundary onto where they meet, as
   far as every cell it moves keeps positive orientation and its quality: no cell's radius ratio drops below the
   smaller of its own and :data:`SNAP_MIN_QUALITY`, nor its smallest dihedral angle below the smaller of its own
   and :data:`SNAP_MIN_DIHEDRAL` (the MeshOptimizer's bounds).  A move that would break that is halved, up to
   :data:`SNAP_ROUNDS` times, then given up.  Nodes on two interfaces (where three regions meet) stay.  Most moves
   given up belong to cells whose every vertex is on the interface: snapped, they would be flat.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..optimize.measures import mean_edge_length
from .simplicial import Mesh
from ..parameters import OptimizeParameters
from .quality import dihedral_angles, signed_radius_ratio
from .tags import facet_sides, region_labels, region_tags
from .topology import vertex_incidence

#: Newton steps towards f_a = f_b.
SNAP_STEPS = 3
#: a node moves at most this x the mean edge length.
SNAP_REACH = 0.5
#: times a move that spoils a cell is halved before it is given up.
SNAP_ROUNDS = 6
#: a snapped cell keeps at least this radius ratio and this smallest dihedral angle (degrees), or its own where
#: lower: the MeshOptimizer's default bounds, so that snapping undoes none of its work.
SNAP_MIN_QUALITY = OptimizeParameters().min_quality
SNAP_MIN_DIHEDRAL = OptimizeParameters().min_dihedral


def largest_label(functions: dict, points: np.ndarray) -> np.ndarray:
    """(m,) the label whose f is largest at each of the (m, k) points; ties go to the lower label.

    ``functions`` : label -> callable (m, k) -> (m,), f > 0 inside that label (about its signed distance).
    """
    labels = sorted(functions)
    values = np.stack([functions[label](points) for label in labels], axis=1)
    return np.asarray(labels, np.int64)[np.argmax(values, axis=1)]


def interface_nodes(cells: np.ndarray, index: np.ndarray, n_points: int):
    """The nodes that may move onto an interface: those on exactly one interface.

    Parameters
    ----------
    cells : (m, k + 1) int64; index : (m,) int, each cell's region as an index into the sorted labels

    Returns
    -------
    nodes : (p,) int64; a, b : (p,) int64, the region indices on the two sides of each node's interface (a < b);
    rim : (p,) bool, True for the nodes on the boundary too (where the interface meets it)
    """
    facets, side, boundary, low, high = facet_sides(cells, index)
    k = facets.shape[1]
    node = facets[low].ravel()
    rows = np.unique(np.column_stack([node, np.repeat(side[low], k), np.repeat(side[high], k)]), axis=0)
    nodes, count = np.unique(rows[:, 0], return_counts=True)
    chosen = rows[np.isin(rows[:, 0], nodes[count == 1])]
    on_boundary = np.zeros(n_points, bool)
    on_boundary[facets[boundary].ravel()] = True
    return chosen[:, 0], chosen[:, 1], chosen[:, 2], on_boundary[chosen[:, 0]]


def projected(functions: list, a: np.ndarray, b: np.ndarray, x: np.ndarray, reach: float, surface=None,
              rim=None) -> np.ndarray:
    """(p, k) each point moved by :data:`SNAP_STEPS` Newton steps onto functions[a] = functions[b] (each an
    :class:`~bitemesh.core.grid.sampled.ImplicitGrid`), at most ``reach`` from where it was; the points where ``rim``
    (p,) is True onto the curve (3D) or the point (2D) where that interface meets ``surface`` = 0 (the union's f, an
    ImplicitGrid), by the least step that zeroes both linearised."""
    moved = x.copy()
    rim = np.zeros(len(x), bool) if rim is None or surface is None else rim
    for pair in np.unique(np.column_stack([a, b]), axis=0):
        rows = np.flatnonzero((a == pair[0]) & (b == pair[1]))
        first, second = functions[pair[0]], functions[pair[1]]
        y, on_rim = moved[rows], rim[rows]
        for _ in range(SNAP_STEPS):
            gap = first.evaluate(y) - second.evaluate(y)
            slope = first.gradient(y) - second.gradient(y)
            step = -(gap / np.maximum(np.einsum("ij,ij->i", slope, slope), 1e-12))[:, None] * slope
            if on_rim.any():
                both = np.stack([slope[on_rim], surface.gradient(y[on_rim])], axis=1)    # (r, 2, k)
                values = np.column_stack([gap[on_rim], surface.evaluate(y[on_rim])])
                gram = both @ both.transpose(0, 2, 1) + 1e-12 * np.eye(2)
                step[on_rim] = -np.einsum("rck,rc->rk", both, np.linalg.solve(gram, values[..., None])[..., 0])
            y = y + step
        moved[rows] = y
    step = moved - x
    length = np.linalg.norm(step, axis=1, keepdims=True)
    return x + step * np.minimum(1.0, reach / np.maximum(length, 1e-300))


def snap_interfaces(mesh: Mesh, regions: np.ndarray, functions: dict, surface=None, *,
                    min_quality: float = SNAP_MIN_QUALITY, min_dihedral: float = SNAP_MIN_DIHEDRAL) -> Mesh:
    """``mesh`` with the nodes of its interfaces moved onto them, as far as the cells allow (see the module).

    Parameters
    ----------
    mesh : a valid domain, cells positively oriented; its cell data is kept as it is (snap before the quality)
    regions : (m,) int, each cell's label
    functions : label -> :class:`~bitemesh.core.grid.sampled.ImplicitGrid`, f of each label in the mesh's frame
    surface : the union's f (an ImplicitGrid, the f the mesh's boundary is on), or None: then the nodes where an
        interface meets the boundary stay; given, they move along the boundary onto the interface
    min_quality, min_dihedral : no moved cell ends below this radius ratio or smallest dihedral angle (degrees),
        unless it was already

    Returns
    -------
    Mesh with the same cells and tags, the interface nodes moved (input units).
    """
    labels = region_labels(list(functions))
    index = np.searchsorted(labels, regions)
    nodes, a, b, rim = interface_nodes(mesh.cells, index, len(mesh.points))
    if surface is None:
        nodes, a, b, rim = nodes[~rim], a[~rim], b[~rim], rim[~rim]
    if len(nodes) == 0:
        return mesh
    points = mesh.points
    cells = mesh.cells[np.unique(vertex_incidence(len(points), mesh.cells)[nodes].indices)]   # those that move
    grids = [functions[label] for label in labels]
    reach = SNAP_REACH * mean_edge_length(points, cells)
    step = projected(grids, a, b, points[nodes], reach, surface, rim) - points[nodes]
    floor = np.minimum(signed_radius_ratio(points, cells), min_quality)
    angle_floor = np.minimum(np.nanmin(dihedral_angles(points, cells), axis=1), min_dihedral)
    scale = np.ones(len(nodes))
    where = np.full(len(points), -1)
    where[nodes] = np.arange(len(nodes))
    for round_ in range(SNAP_ROUNDS + len(nodes) + 1):   # halvings, then zeroings: each removes a move or ends
        trial = points.copy()
        trial[nodes] += scale[:, None] * step
        bad = ((signed_radius_ratio(trial, cells) < floor)
               | (np.nanmin(dihedral_angles(trial, cells), axis=1) < angle_floor))
        culprits = where[cells[bad]]
        culprits = np.unique(culprits[culprits >= 0])
        culprits = culprits[scale[culprits] > 0]
        if len(culprits) == 0:
            return replace(mesh, points=trial)
        scale[culprits] *= 0.5 if round_ < SNAP_ROUNDS else 0.0
    return mesh   # not reached: after the zeroings every touched cell is as it was


@dataclass(frozen=True, eq=False)
class LabelRegions:
    """The regions of a label map of several labels, as the meshing spine uses them.

    Attributes
    ----------
    functions : label -> :class:`~bitemesh.core.grid.sampled.ImplicitGrid`, f > 0 inside each label (about its signed
        distance), in the source's local frame
    """

    functions: dict

    @property
    def labels(self) -> np.ndarray:
        return region_labels(list(self.functions))

    def node_regions(self, points: np.ndarray) -> np.ndarray:
        """(n,) int64 the index into :attr:`labels` of the label whose f is largest at each of the (n, k) points."""
        return np.searchsorted(self.labels, largest_label(self.functions, points))

    def onto_interfaces(self, points: np.ndarray, reach: float, surface=None) -> np.ndarray:
        """(n, k) the points moved onto the interface between the two labels whose f is largest at each, at most
        ``reach`` (local units) from where they were; given ``surface`` (the union's f, an ImplicitGrid), onto where
        that interface meets surface = 0."""
        grids = [self.functions[label] for label in self.labels]
        top = np.argsort(-np.stack([grid.evaluate(points) for grid in grids], axis=1), axis=1, kind="stable")
        first, second = np.sort(top[:, :2], axis=1).T
        return projected(grids, first, second, points, reach, surface, np.ones(len(points), bool))

    def __call__(self, mesh: Mesh, function=None) -> Mesh:
        """The :attr:`~bitemesh.core.sources.source.Source.tagging` of a label map: :func:`label_regions`, the nodes
        where an interface meets the boundary moved along ``function`` = 0 (the union's f, an ImplicitGrid) when
        given."""
        return label_regions(mesh, self.functions, surface=function)


def label_regions(mesh: Mesh, functions: dict, *, snap: bool = True, surface=None) -> Mesh:
    """``mesh`` cut into one region per label (:func:`largest_label` at the cells' centroids), its interface nodes
    snapped (:func:`snap_interfaces`, when ``snap`` and there are two labels or more), tagged by
    :func:`~bitemesh.core.mesh.tags.region_tags`.

    ``functions`` : label -> :class:`~bitemesh.core.grid.sampled.ImplicitGrid`, f > 0 inside each label (mesh's frame);
    ``surface`` : the union's f, or None (see :func:`snap_interfaces`).
    """
    if len(functions) == 1:
        regions = np.full(len(mesh.cells), next(iter(functions)), np.int64)
    else:
        regions = largest_label(functions, mesh.points[mesh.cells].mean(axis=1))
        if snap:
            mesh = snap_interfaces(mesh, regions, functions, surface)
    return region_tags(mesh, regions, list(functions))
