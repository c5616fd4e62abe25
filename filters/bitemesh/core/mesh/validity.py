"""Validity checks of a simplicial mesh (triangles in 2D, tetrahedra in 3D, k-simplices up to 5-D): is it a valid
finite-element domain (:func:`check_valid_domain`), and its boundary's topology (:func:`count_boundary_components`,
:func:`boundary_euler_characteristic`); also the checks of a mesh's arrays that every measure makes.  The element
quality is :mod:`bitemesh.core.mesh.quality`, which re-exports these names.

Topology is computed exactly with integers: the cells across each facet come from a hash table of the facets'
sorted vertices (:func:`~bitemesh.core.mesh.adjacency.cell_neighbours`), and edges are grouped by their sorted vertices
(:func:`~bitemesh.core.mesh.topology.face_groups`).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..errors import InvalidInputError, check_number
from .adjacency import BOUNDARY, NON_MANIFOLD, cell_neighbours, same_side_pairs
from .simplicial import MAX_DIMENSION, Mesh, facet_of, signed_measures
from .topology import (boundary_facets, boundary_stars, distinct_faces, euler_characteristic, face_groups,
                       unique_rows)


def _check_cells(cells, name: str = "cells") -> np.ndarray:
    array = np.asarray(cells)
    if array.ndim != 2 or not 3 <= array.shape[1] <= MAX_DIMENSION + 1 or not np.issubdtype(array.dtype, np.integer):
        raise InvalidInputError(
            f"{name} must be an (m, k + 1) integer array of vertex indices, k = 2 to {MAX_DIMENSION} (triangles, "
            f"tetrahedra, ...), got shape {array.shape} and dtype {array.dtype}")
    if array.size and array.min() < 0:
        raise InvalidInputError(f"{name} holds negative vertex indices (first at cell {int(np.argmin(array.min(1)))})")
    return array.astype(np.int64, copy=False)


def _check_mesh(mesh: Mesh, name: str = "mesh"):
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or not 2 <= points.shape[1] <= MAX_DIMENSION:
        raise InvalidInputError(f"{name}.points must be an (n, k) array, k = 2 to {MAX_DIMENSION}, got shape "
                                f"{points.shape}")
    cells = _check_cells(mesh.cells, f"{name}.cells")
    if cells.shape[1] != points.shape[1] + 1:
        raise InvalidInputError(
            f"{name}.cells must have {points.shape[1] + 1} vertices per cell for {points.shape[1]}D points, "
            f"got {cells.shape[1]}")
    if cells.size and cells.max() >= len(points):
        raise InvalidInputError(
            f"{name}.cells refers to vertex {int(cells.max())} but there are only {len(points)} points")
    return points, cells


def _n_points(cells: np.ndarray) -> int:
    return int(cells.max()) + 1 if cells.size else 0


def boundary_euler_characteristic(mesh: Mesh) -> int:
    """Euler characteristic of the boundary complex of ``mesh``.

    3D: V - E + F of the boundary surface (2 per closed sphere-like surface, 0 per torus).
    2D: V - E of the boundary curves, 0 for any set of closed loops (count them with
    :func:`count_boundary_components`).
    """
    _, cells = _check_mesh(mesh)
    facets = boundary_facets(cells)
    return euler_characteristic(facets)


def count_boundary_components(mesh: Mesh) -> int:
    """Number of connected pieces of the boundary: loops in 2D, closed surfaces in 3D (for a valid domain)."""
    _, cells = _check_mesh(mesh)
    facets = boundary_facets(cells)
    if len(facets) == 0:
        return 0
    n_points = _n_points(cells)
    edges = distinct_faces(facets, 2)
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_points,) * 2)
    labels = csgraph.connected_components(graph, directed=False)[1]
    return len(np.unique(labels[np.unique(facets)]))


def _found(count: int, what: str, first: str) -> str:
    return f"{count} {what} (first: {first})"


#: the names of the faces of a boundary by their vertex count: plural, singular.
_FACES = {1: ("vertices", "point"), 2: ("edges", "edge"), 3: ("triangles", "triangle"),
          4: ("tetrahedra", "tetrahedron"), 5: ("4-simplices", "4-simplex")}


def _manifold_problems(facets: np.ndarray, n_points: int) -> list:
    """Problems of the boundary ``facets`` (oriented, (b, k)) as a closed (k-1)-manifold: each of its ridges (the
    facets' faces of k - 1 vertices: vertices in 2D, edges in 3D) in exactly two boundary facets, and the boundary
    facets at each vertex one star, joined across the ridges through the vertex (in 3D a fan)."""
    problems = []
    size = facets.shape[1]
    (facet_name, _), (ridge_name, ridge_one) = _FACES[size], _FACES[size - 1]
    corners = np.array(list(combinations(range(size), size - 1)))
    ridges, inverse, counts = face_groups(facets, corners)
    bad = np.flatnonzero(counts != 2)
    if len(bad):
        first = ridges[bad[0]].tolist()
        problems.append(_found(len(bad), f"boundary {ridge_name} not in exactly two boundary {facet_name} "
                               "(non-manifold boundary)",
                               f"{ridge_one} {first[0] if size == 2 else tuple(first)} in {counts[bad[0]]}"))
    if size == 2 or not len(facets):
        return problems
    stars = boundary_stars(facets, n_points, ridges=(corners, inverse))
    bad = np.flatnonzero(stars > 1)
    if len(bad):
        shape = "fan" if size == 3 else "star"
        problems.append(_found(len(bad), f"boundary vertices whose boundary {facet_name} form more than one {shape} "
                               "(non-manifold boundary, e.g. cells touching at a vertex)",
                               f"point {bad[0]} with {stars[bad[0]]} {shape}s"))
    return problems


def check_valid_domain(mesh: Mesh, volume_rtol: float = 1e-12) -> list:
    """Problems that keep ``mesh`` from being a valid finite-element domain; an empty list means valid.

    Checked: non-finite points; inverted cells (signed volume < -tol) and flat cells (|volume| <= tol), with
    tol = ``volume_rtol`` * (longest edge of the cell)^k; duplicate cells; facets shared by more than two cells;
    facets whose two cells lie on the same side of it (overlapping cells); a boundary that is not a closed
    (k-1)-manifold (3D: each boundary edge in exactly two boundary triangles and the boundary triangles at each
    vertex forming one fan; 2D: each boundary vertex in exactly two boundary edges); unused points.
    Not checked: geometric self-intersection of cells that share no facet.

    Parameters
    ----------
    mesh : Mesh with positively oriented cells
    volume_rtol : relative tolerance of the volume test, >= 0

    Returns
    -------
    list of str, one message per kind of problem, each with a count and a first example.
    Raises :class:`InvalidInputError` if the arrays are malformed (shapes, indices out of range).
    """
    points, cells = _check_mesh(mesh)
    volume_rtol = check_number(volume_rtol, "volume_rtol", low=0.0)
    k = points.shape[1]
    problems = []

    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if len(bad):
        problems.append(_found(len(bad), "points with NaN or infinite coordinates", f"point {bad[0]}"))

    volume = signed_measures(points, cells)
    longest = np.zeros(len(cells))   # squared, edge by edge: (m, k) temporaries only
    for i, j in combinations(range(k + 1), 2):
        np.maximum(longest, np.square(points[cells[:, j]] - points[cells[:, i]]).sum(axis=1), out=longest)
    tolerance = volume_rtol * np.sqrt(longest) ** k
    for mask, what in ((volume < -tolerance, "inverted cells (negative volume)"),
                       (np.abs(volume) <= tolerance, f"flat cells (|volume| <= {volume_rtol:g} * longest edge^{k})")):
        bad = np.flatnonzero(mask)
        if len(bad):
            problems.append(_found(len(bad), what, f"cell {bad[0]}, volume {volume[bad[0]]:.3g}"))

    _, inverse, counts = unique_rows(cells)
    bad = np.flatnonzero(counts[inverse] > 1)
    if len(bad):
        problems.append(_found(len(bad), "cells with the same vertices as another cell", f"cell {bad[0]}"))

    # facets by the cells across them (a hash table of the cells' facet rows, no table of every facet)
    across = cell_neighbours(cells)
    bad = np.flatnonzero(across.ravel() == NON_MANIFOLD)
    if len(bad):
        facets = facet_of(cells, bad // (k + 1), bad % (k + 1))
        unique, inverse, counts = unique_rows(facets)
        problems.append(_found(len(unique), "facets shared by more than two cells",
                               f"facet {tuple(np.sort(facets[0]).tolist())} in {counts[inverse[0]]} cells"))
    count, (first, second) = same_side_pairs(cells, across)
    if count:
        problems.append(_found(count, "facets with both cells on the same side (overlapping cells)",
                               f"cells {first} and {second}"))

    problems += _manifold_problems(facet_of(cells, *np.nonzero(across == BOUNDARY)), len(points))

    bad = np.flatnonzero(np.bincount(cells.ravel(), minlength=len(points)) == 0)
    if len(bad):
        problems.append(_found(len(bad), "points used by no cell", f"point {bad[0]}"))
    return problems
