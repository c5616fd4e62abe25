"""The cells that touch (:mod:`bitemesh.core.mesh.adjacency`): neighbours across facets, pairs on interior facets and
rings around interior edges, against the sorted facet table and the definitions."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from bitemesh.core.mesh.adjacency import BOUNDARY, NON_MANIFOLD, cell_neighbours, edge_rings, facet_pairs, replaced
from bitemesh.core.mesh.simplicial import facets_of, signed_measures
from bitemesh.core.mesh.topology import facet_table, neighbour_pairs


def positive_delaunay(dim: int, n: int, seed: int):
    points = np.random.default_rng(seed).random((n, dim))
    cells = Delaunay(points).simplices.astype(np.int64)
    flip = signed_measures(points, cells) < 0
    cells[flip, :2] = cells[flip, 1::-1]
    return points, cells


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1])
def test_neighbours_are_the_cells_sharing_each_facet(dim, seed):
    points, cells = positive_delaunay(dim, 300, seed)
    cells = cells[np.random.default_rng(seed).permutation(len(cells))]
    _, inverse, counts = facet_table(cells)
    a, b = neighbour_pairs(inverse)
    expected = np.full(cells.shape, BOUNDARY)
    expected.ravel()[a], expected.ravel()[b] = b // (dim + 1), a // (dim + 1)
    assert np.array_equal(cell_neighbours(cells), expected)
    assert (cell_neighbours(cells) == BOUNDARY).sum() == (counts == 1).sum()


def test_a_facet_held_by_three_cells_is_marked():
    cells = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5], [3, 1, 2, 6]])
    across = cell_neighbours(cells)
    assert np.array_equal(across[:3, 3], [NON_MANIFOLD] * 3)
    assert across[0, 0] == 3 and across[3, 3] == 0   # (1, 2, 3) is shared by cells 0 and 3 only


@pytest.mark.parametrize("dim", [2, 3])
def test_facet_pairs_are_the_interior_facets_once(dim):
    points, cells = positive_delaunay(dim, 300, 2)
    across = cell_neighbours(cells)
    cell_a, cell_b, a, b, facet = facet_pairs(cells, across)
    assert len(cell_a) == (across >= 0).sum() // 2 and np.all(cell_a < cell_b)
    for c, d, x, y, f in zip(cell_a, cell_b, a, b, facet):
        assert set(cells[c]) == set(f) | {x} and set(cells[d]) == set(f) | {y}
    # oriented out of cell_a: the far vertex of cell_a lies behind the facet
    outward = signed_measures(points, np.column_stack([facet, a]))
    assert np.all(outward < 0) if dim == 3 else np.all(outward > 0)
    start = np.zeros(len(cells), bool)
    start[::5] = True
    some = facet_pairs(cells, across, start)[0:2]
    expected = start[cell_a] | start[cell_b]
    assert np.array_equal(some[0], cell_a[expected]) and np.array_equal(some[1], cell_b[expected])
    wanted = np.zeros(len(cells), bool)
    wanted[1::3] = True
    some = facet_pairs(cells, across, start, wanted)
    expected &= wanted[cell_a] | wanted[cell_b]
    for got, every in zip(some, (cell_a, cell_b, a, b, facet)):
        assert np.array_equal(got, every[expected])


def test_edge_rings_close_positively_around_every_interior_edge():
    points, cells = positive_delaunay(3, 400, 3)
    across = cell_neighbours(cells)
    rings = edge_rings(cells, across, 40)
    seen = set()
    for n, (a, b, ring, around) in rings.items():
        for x, y, r, c in zip(a, b, ring, around):
            assert x < y and (x, y) not in seen
            seen.add((x, y))
            fan = np.column_stack([np.full(n, x), np.full(n, y), r, np.roll(r, -1)])
            assert np.array_equal(np.sort(fan, axis=1), np.sort(cells[c], axis=1))
            assert np.all(signed_measures(points, fan) > 0)
    # the interior edges: those not on a boundary facet
    boundary = facets_of(cells)[across == BOUNDARY]
    on_boundary = {tuple(sorted(e)) for f in boundary for e in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2]))}
    every = {tuple(sorted((c[i], c[j]))) for c in cells for i in range(4) for j in range(i + 1, 4)}
    assert seen == every - on_boundary
    # with start cells: the rings that hold one, each once; no ring longer than max_ring
    start = np.zeros(len(cells), bool)
    start[::7] = True
    short = edge_rings(cells, across, 5, start)
    for n in range(3, 6):
        held = start[rings[n][3]].any(axis=1)
        assert sorted(zip(*short[n][:2])) == sorted(zip(rings[n][0][held], rings[n][1][held]))
    assert set(short) == {3, 4, 5}


@pytest.mark.parametrize("dim", [2, 3])
def test_replaced_cells_keep_their_neighbours_up_to_date(dim):
    points, cells = positive_delaunay(dim, 300, 4)
    rng = np.random.default_rng(4)
    removed = rng.random(len(cells)) < 0.1
    added = cells[removed][::-1]   # the same place filled again, in another order
    new_cells, across = replaced(cells, cell_neighbours(cells), removed, added)
    assert np.array_equal(new_cells, np.concatenate([cells[~removed], added]))
    assert np.array_equal(across, cell_neighbours(new_cells))
