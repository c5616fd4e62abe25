"""Boundary and region tags: every boundary facet (triangle in 3D, edge in 2D) of a mesh gets a tag > 0, every cell a
region, and the names travel with them (:attr:`~bitemesh.core.mesh.simplicial.Mesh.tag_names`, meshio's field_data and
gmsh's physical names: name -> (tag, dimension), dimension k for a region, k - 1 for a facet tag).

Three ways to tag, one per kind of source:

- **scattered points** (:func:`component_tags`): one tag per connected piece of the boundary, ``BOUNDARY_1``,
  ``BOUNDARY_2``, ... by decreasing area (length in 2D), ties by the first facet; one region, ``DOMAIN``.
- **labelled contours** (:func:`surface_tags`): the surface whose implicit gives f at the facet's centroid, tag =
  its position in the source's names + 1 (biv-me: EPI 1, LV_ENDO 2, RV_ENDO 3, BASE 4); one region, ``MYOCARDIUM``
  for a heart's myocardium, else ``DOMAIN``; an LV-only myocardium renamed as cardiac-geometries' LV (EPI 7, ENDO 6,
  BASE 5, MYOCARDIUM 8: :func:`renamed_tags`).
- **label maps** (:func:`region_tags`): each cell in the region of the label whose f is largest at its centroid
  (Region = the label value, ``REGION_<label>``); boundary facets by the region they bound (``BOUNDARY_<label>``),
  facets between two regions by the pair (``INTERFACE_<a>_<b>``, a < b).  The mesh is the union's, so the regions
  share the nodes of their interfaces; :func:`~bitemesh.core.mesh.interfaces.snap_interfaces` moves those nodes onto the
  interface first.

Facets are oriented out of the domain (boundary) or out of the region with the lower tag (interfaces), as
:class:`~bitemesh.core.mesh.simplicial.Mesh` says.  Names are listed only for tags some facet or cell carries.
"""
from __future__ import annotations


import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..errors import InvalidInputError
from .simplicial import Mesh, facet_measures
from .topology import facet_table, faces_of, unique_rows

#: the one region of a mesh of one domain (scattered points, labelled contours other than a myocardium).
DOMAIN = "DOMAIN"
#: the region of a heart's myocardium meshed from labelled contours.
MYOCARDIUM = "MYOCARDIUM"


def boundary_pieces(facets: np.ndarray) -> np.ndarray:
    """(b,) labels 0 .. c - 1 of the facets joined through shared ridges (edges in 3D, vertices in 2D)."""
    if len(facets) == 0:
        return np.zeros(0, np.int64)
    _, ridge, _ = unique_rows(faces_of(facets, facets.shape[1] - 1))
    ridge = ridge.reshape(len(facets), -1)
    n = len(facets)
    rows = np.repeat(np.arange(n), ridge.shape[1])
    graph = sparse.coo_matrix((np.ones(ridge.size), (rows, n + ridge.ravel())), shape=(n + ridge.max() + 1,) * 2)
    return csgraph.connected_components(graph, directed=False)[1][:n].astype(np.int64)


def _names(mesh: Mesh, facet_tags: np.ndarray, facet_names: dict, regions: np.ndarray, region_names: dict) -> dict:
    """name -> (tag, dimension) for the facet tags and regions that occur, facet tags first, each by tag."""
    dim = mesh.dim
    named = {facet_names[tag]: (int(tag), dim - 1) for tag in np.unique(facet_tags)}
    named.update({region_names[tag]: (int(tag), dim) for tag in np.unique(regions)})
    return named


def _one_region(mesh: Mesh, facets: np.ndarray, facet_tags: np.ndarray, facet_names: dict, region: str) -> Mesh:
    regions = np.ones(len(mesh.cells), np.int32)
    return mesh.with_tags(facets, facet_tags, _names(mesh, facet_tags, facet_names, regions, {1: region}), regions)


def component_tags(mesh: Mesh, region: str = DOMAIN) -> Mesh:
    """``mesh`` with its boundary facets tagged by connected piece: ``BOUNDARY_i`` (tag i) for the i-th largest by
    area, one region named ``region``.

    Parameters
    ----------
    mesh : a valid domain, (m, k + 1) cells positively oriented

    Returns
    -------
    Mesh with facets (b, k) the boundary, facet_tags (b,) int32 in 1 .. c, Region (m,) int32 = 1.
    """
    facets = facet_table(mesh.cells)
    facets = facets[0][facets[2][facets[1]] == 1]
    piece = boundary_pieces(facets)
    count = int(piece.max()) + 1 if len(piece) else 0
    area = np.bincount(piece, facet_measures(mesh.points[facets]), minlength=count)
    first = np.full(count, len(piece))
    np.minimum.at(first, piece, np.arange(len(piece)))
    order = np.lexsort((first, -area))            # decreasing area, ties by the first facet
    rank = np.empty(count, np.int64)
    rank[order] = np.arange(count)
    tags = (rank[piece] + 1).astype(np.int32)
    return _one_region(mesh, facets, tags, {i: f"BOUNDARY_{i}" for i in range(1, count + 1)}, region)


def surface_tags(mesh: Mesh, active_surface, names, region: str = DOMAIN) -> Mesh:
    """``mesh`` with each boundary facet tagged by the surface that bounds the domain there.

    Parameters
    ----------
    mesh : a valid domain of a labelled source, in the frame ``active_surface`` takes
    active_surface : callable (b, k) points -> (b,) int index into ``names`` of the surface whose implicit gives f
        (:meth:`~bitemesh.core.sources.contours.function.LabelledImplicit.active_surface`)
    names : the surface names (biv-me: EPI, LV_ENDO, RV_ENDO, BASE); tag = position + 1
    region : the name of the one region

    Returns
    -------
    Mesh with facets (b, k) the boundary, facet_tags (b,) int32, Region (m,) int32 = 1.
    """
    facets = facet_table(mesh.cells)
    facets = facets[0][facets[2][facets[1]] == 1]
    surface = np.asarray(active_surface(mesh.points[facets].mean(axis=1)), np.int64)
    if len(surface) and (surface.min() < 0 or surface.max() >= len(names)):
        raise InvalidInputError(f"active_surface gave index {int(surface.max())}, beyond the {len(names)} names "
                                f"{tuple(names)}; it must index the names, 0 to {len(names) - 1}")
    return _one_region(mesh, facets, (surface + 1).astype(np.int32),
                       {i + 1: name for i, name in enumerate(names)}, region)


def renamed_tags(mesh: Mesh, facet_names: dict, region: int) -> Mesh:
    """``mesh`` (one region, tagged by :func:`surface_tags`) with its facet tags renamed and renumbered by
    ``facet_names`` (old name -> (new name, new tag)) and its region numbered ``region``."""
    old = {name: tag for name, (tag, dimension) in mesh.tag_names.items() if dimension == mesh.dim - 1}
    table = np.zeros(max(old.values(), default=0) + 1, np.int32)
    names = {}
    for name, tag in old.items():
        new_name, new_tag = facet_names.get(name, (name, tag))
        table[tag], names[new_name] = new_tag, (new_tag, mesh.dim - 1)
    names.update({name: (region, dimension) for name, (_, dimension) in mesh.tag_names.items()
                  if dimension == mesh.dim})
    return mesh.with_tags(mesh.facets, table[mesh.facet_tags], names, np.full(len(mesh.cells), region, np.int32))


def region_labels(labels) -> np.ndarray:
    """(r,) int64 the region labels, sorted: each a whole number in 1 .. 2^31 - 1 (they are the Region values)."""
    labels = np.unique(np.asarray(labels, dtype=np.int64))
    if len(labels) == 0 or labels[0] < 1 or labels[-1] > np.iinfo(np.int32).max:
        raise InvalidInputError(f"region labels must be whole numbers in [1, {np.iinfo(np.int32).max}], got "
                                f"{labels.tolist()}; relabel the label map (0 is the background)")
    return labels


def interface_tag(labels: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The facet tags of the interfaces between regions ``labels[a]`` and ``labels[b]`` (a < b, indices into the
    r sorted labels): r + 1 + the pair's position among all pairs in order (0, 1), (0, 2), ..., (r - 2, r - 1).
    Boundary facets of region i take tag i + 1, so that every tag follows from the labels alone."""
    r = len(labels)
    return (r + 1 + a * (2 * r - a - 1) // 2 + (b - a - 1)).astype(np.int32)


def facet_sides(cells: np.ndarray, index: np.ndarray):
    """The facet table of ``cells`` (:func:`~bitemesh.core.mesh.topology.facet_table`) split by the regions on each
    side.

    Parameters
    ----------
    cells : (m, k + 1) int64; index : (m,) int, a number per cell, ordered as the region labels

    Returns
    -------
    facets : (m (k + 1), k) every facet of every cell, oriented out of its cell; side : (m (k + 1),) ``index`` of
    each row's cell; boundary : (m (k + 1),) bool, the rows on the boundary; low, high : (p,) int64, the two rows of
    each interface facet (different numbers on its sides), ``low`` the row of the side with the lower number
    """
    facets, inverse, counts = facet_table(cells)
    side = np.repeat(index, cells.shape[1])
    order = np.lexsort((side, inverse))   # the two rows of an interior facet together, the lower number first
    first, second = order[:-1], order[1:]
    pair = (inverse[first] == inverse[second]) & (side[first] != side[second])
    return facets, side, counts[inverse] == 1, first[pair], second[pair]


def region_tags(mesh: Mesh, regions: np.ndarray, labels) -> Mesh:
    """``mesh`` with its cells in regions and its facets tagged by the regions they bound.

    Parameters
    ----------
    mesh : a valid domain, (m, k + 1) cells positively oriented
    regions : (m,) int, each cell's label, one of ``labels``
    labels : the region labels (:func:`region_labels`)

    Returns
    -------
    Mesh with Region (m,) int32 the labels; facets: the boundary (tag i + 1 for ``labels[i]``, ``BOUNDARY_<label>``)
    and the interfaces between two regions (:func:`interface_tag`, ``INTERFACE_<a>_<b>``), oriented out of the
    domain or out of the region with the lower label.
    """
    labels = region_labels(labels)
    regions = np.asarray(regions, dtype=np.int64)
    index = np.searchsorted(labels, regions)
    if len(regions) != len(mesh.cells) or np.any(labels[np.minimum(index, len(labels) - 1)] != regions):
        raise InvalidInputError(f"regions must hold one of the labels {labels.tolist()} for each of the "
                                f"{len(mesh.cells)} cells")
    facets, side, boundary, low, high = facet_sides(mesh.cells, index)
    keep = np.sort(np.concatenate([np.flatnonzero(boundary), low]))
    tags = np.zeros(len(facets), np.int32)
    tags[boundary] = side[boundary] + 1
    tags[low] = interface_tag(labels, side[low], side[high])
    names = {i + 1: f"BOUNDARY_{labels[i]}" for i in np.unique(side[boundary])}
    for a, b in np.unique(np.column_stack([side[low], side[high]]), axis=0):
        names[int(interface_tag(labels, a, b))] = f"INTERFACE_{labels[a]}_{labels[b]}"
    region_values = labels[index].astype(np.int32)
    tag_names = _names(mesh, tags[keep], names, region_values, {int(label): f"REGION_{label}" for label in labels})
    return mesh.with_tags(facets[keep], tags[keep], tag_names, region_values)


def closed_by_fans(points: np.ndarray, triangles: np.ndarray):
    """A consistently oriented triangle patch (t, 3) on (n, 3) points with each hole closed by a fan from its rim's
    centroid (a cavity's endocardium closed across its valves at the base): (points (n + h, 3), the centroids
    appended; triangles (t + r, 3), the caps oriented as the patch)."""
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    keys = directed[:, 0] * len(points) + directed[:, 1]
    rim = directed[~np.isin(keys, directed[:, 1] * len(points) + directed[:, 0])]
    if not len(rim):
        return points, triangles
    graph = sparse.coo_matrix((np.ones(len(rim)), (rim[:, 0], rim[:, 1])), shape=(len(points),) * 2)
    loop = csgraph.connected_components(graph, directed=False)[1][rim[:, 0]]
    numbers, loop = np.unique(loop, return_inverse=True)
    centres = np.array([points[np.unique(rim[loop == number])].mean(axis=0) for number in range(len(numbers))])
    caps = np.column_stack([rim[:, 1], rim[:, 0], len(points) + loop])   # reversed: continuing the orientation
    return np.vstack([points, centres]), np.vstack([triangles, caps])


def enclosed_volume(points: np.ndarray, triangles: np.ndarray) -> float:
    """|volume| (input units^3) enclosed by a consistently oriented triangle patch (t, 3), its holes closed
    (:func:`closed_by_fans`)."""
    points, triangles = closed_by_fans(points, triangles)
    corners = points[triangles]
    return abs(float(np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() / 6))


def cavity_volumes(mesh: Mesh, names=("LV_ENDO", "RV_ENDO")) -> dict:
    """name -> the volume (input units^3) of the cavity its tagged facets bound, closed across its openings
    (:func:`enclosed_volume`), for each of ``names`` the mesh tags."""
    volumes = {}
    for name in names:
        if name in mesh.tag_names and mesh.facets is not None:
            facets = mesh.facets[mesh.facet_tags == mesh.tag_names[name][0]]
            if len(facets):
                volumes[name] = enclosed_volume(mesh.points, facets)
    return volumes


def lips(mesh: Mesh, first, second) -> np.ndarray:
    """(e, 2) the edges (point ids) where the boundary turns from a facet tagged with one of the names ``first`` to one
    tagged with one of ``second``, the edge in no other facet: the lip of a hole through the wall between them (a
    cavity's endocardium and the epicardium; an edge in four facets is a pinch, the wall there closed on both sides)."""
    if mesh.facets is None:
        return np.zeros((0, 2), np.int64)
    side = np.zeros(len(mesh.facets), np.int64)
    for value, names in ((1, first), (2, second)):
        side[np.isin(mesh.facet_tags, [mesh.tag_names[name][0] for name in names if name in mesh.tag_names])] = value
    edges = np.sort(np.concatenate([mesh.facets[:, [0, 1]], mesh.facets[:, [1, 2]], mesh.facets[:, [2, 0]]]), axis=1)
    unique, inverse, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    sides = np.zeros((len(unique), 3), np.int64)
    np.add.at(sides, (inverse.ravel(), np.tile(side, 3)), 1)
    return unique[(counts == 2) & (sides[:, 1] == 1) & (sides[:, 2] == 1)]
