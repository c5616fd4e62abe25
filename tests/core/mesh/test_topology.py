"""Grouping faces (:func:`bitemesh.core.mesh.topology.face_groups`, behind unique_rows, distinct_faces and CellComplex)
and the same-side test of the validity check, against numpy's sorting and the definitions."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bitemesh.core.mesh.adjacency import cell_neighbours, same_side_pairs
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.mesh.topology import (CellComplex, boundary_facets, connected_components, distinct_faces,
                                         face_groups, faces_of, unique_rows)
from bitemesh.core.mesh.validity import check_valid_domain

from .test_adjacency import positive_delaunay


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 4), st.integers(1, 60), st.integers(0, 300), st.integers(0, 2**32 - 1))
def test_unique_rows_and_distinct_faces_are_numpys(width, n_points, n_rows, seed):
    """Both paths (grouped by the lowest vertex when the rows outnumber the vertices, sorted keys otherwise) give
    np.unique's sorted rows, inverse and counts."""
    rows = np.random.default_rng(seed).integers(0, n_points, (n_rows, width))
    unique, inverse, counts = unique_rows(rows)
    expected = np.unique(np.sort(rows, axis=1), axis=0, return_inverse=True, return_counts=True)
    assert np.array_equal(unique.reshape(-1, width), expected[0].reshape(-1, width))
    assert np.array_equal(inverse, expected[1].ravel()) and np.array_equal(counts, expected[2])
    for size in range(1, width + 1):
        faces = np.sort(faces_of(rows, size).reshape(-1, size), axis=1)
        assert np.array_equal(distinct_faces(rows, size).reshape(-1, size),
                              np.unique(faces, axis=0).reshape(-1, size))


@pytest.mark.parametrize("dim", [2, 3])
def test_face_groups_number_each_face_of_each_cell(dim):
    _, cells = positive_delaunay(dim, 200, 4)
    corners = np.array([[1, 0], [2, 1]]) if dim == 2 else np.array([[3, 1, 0], [0, 2, 3]])
    unique, inverse, counts = face_groups(cells, corners)
    assert inverse.shape == (len(cells), 2) and counts.sum() == inverse.size
    for c, q in np.ndindex(inverse.shape):
        assert np.array_equal(unique[inverse[c, q]], np.sort(cells[c, corners[q]]))
    assert np.array_equal(np.bincount(inverse.ravel()), counts)
    assert face_groups(cells, corners, inverse=False)[1] is None


@pytest.mark.parametrize("dim", [2, 3])
def test_same_side_pairs_find_each_overlap_once(dim):
    """A consistently oriented Delaunay mesh has none; a cell turned inside out lies on the same side as each of
    its neighbours (k + 1 facets inside, fewer on the hull)."""
    _, cells = positive_delaunay(dim, 200, 5)
    assert same_side_pairs(cells, cell_neighbours(cells)) == (0, (-1, -1))
    across = cell_neighbours(cells)
    inner = int(np.flatnonzero((across >= 0).all(axis=1))[0])
    cells[inner, :2] = cells[inner, 1::-1]
    count, (first, second) = same_side_pairs(cells, cell_neighbours(cells))
    assert count == dim + 1 and inner in (first, second)
    assert any(problem.startswith(f"{dim + 1} facets with both cells on the same side")
               for problem in check_valid_domain(Mesh(np.random.default_rng(5).random((200, dim)), cells)))


@settings(max_examples=30, deadline=None)
@given(st.sampled_from([2, 3]), st.floats(0.05, 0.95), st.integers(0, 2**32 - 1))
def test_surface_pieces_count_the_boundary_parts_of_any_subset(dim, share, seed):
    """CellComplex.surface_pieces of a random subset of a Delaunay mesh's cells (pinched, in pieces, with holes)
    is the number of parts that connected_components finds in its boundary facets."""
    points, cells = positive_delaunay(dim, 150, seed % 1000)
    keep = np.random.default_rng(seed).random(len(cells)) < share
    surface = boundary_facets(cells[keep])
    expected = int(connected_components(surface).max() + 1) if len(surface) else 0
    assert CellComplex(cells, len(points)).surface_pieces(keep) == expected
