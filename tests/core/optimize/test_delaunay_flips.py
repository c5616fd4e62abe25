"""Flips towards the Delaunay triangulation (the relaxation's local update,
:func:`bitemesh.core.optimize.delaunay_flips.flip_to_delaunay`): from a Delaunay triangulation whose interior nodes
moved, they reach the Delaunay triangulation of the moved nodes, the hull kept; every interior facet ends locally
Delaunay; the boundary, the nodes and the volume stay."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from bitemesh.core.steps.delaunay import delaunay
from bitemesh.core.mesh.adjacency import cell_neighbours
from bitemesh.core.optimize.delaunay_flips import DELAUNAY_GAIN, flip_to_delaunay
from bitemesh.core.mesh.simplicial import Mesh, circumspheres, facets_of, signed_measures
from bitemesh.core.mesh.validity import check_valid_domain
from bitemesh.core.optimize.relax import positive_moves
from bitemesh.core.mesh.topology import boundary_facets, unique_rows


def jittered_grid(dim: int, side: int, seed: int):
    """Nodes of a jittered grid in the unit box and their Delaunay cells, the nodes off the hull then moved by up
    to 0.35 of the spacing (the hull stays: the same domain), but for those whose move would invert a cell
    (:func:`bitemesh.core.optimize.relax.positive_moves`, as in the relaxation)."""
    rng = np.random.default_rng(seed)
    axes = [np.linspace(0.0, 1.0, side)] * dim
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
    nodes += rng.uniform(-0.1, 0.1, nodes.shape) / (side - 1)   # no four nodes on a plane or a circle
    cells = delaunay(nodes)
    inner = np.ones(len(nodes), bool)
    inner[ConvexHull(nodes).vertices] = False
    targets = nodes.copy()
    targets[inner] += rng.uniform(-0.35, 0.35, (inner.sum(), dim)) / (side - 1)
    moved = positive_moves(nodes, targets, cells)
    assert signed_measures(moved, cells).min() > 0 and np.any(moved != nodes)
    return moved, cells


def interior_facet_violations(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(p,) for each interior facet, how far the far vertex of one cell lies inside the other's circumsphere
    (fraction of the squared radius; <= 0: locally Delaunay)."""
    k = points.shape[1]
    facets = np.sort(facets_of(cells).reshape(-1, k), axis=1)
    _, inverse, counts = np.unique(facets, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    rows = np.flatnonzero(counts[inverse] == 2)
    order = rows[np.argsort(inverse[rows], kind="stable")]
    first, second = order[0::2], order[1::2]
    cell_a, far_b = first // (k + 1), cells[second // (k + 1), second % (k + 1)]
    centre, radius = circumspheres(points, cells[cell_a])
    return (radius ** 2 - ((points[far_b] - centre) ** 2).sum(axis=1)) / radius ** 2


@pytest.mark.parametrize("dim, side", [(2, 30), (3, 12)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_moved_nodes_reach_their_delaunay_triangulation(dim, side, seed):
    points, cells = jittered_grid(dim, side, seed)
    assert interior_facet_violations(points, cells).max() > 0.01   # the move made the cells non-Delaunay
    flipped, across = flip_to_delaunay(points, cells)
    assert interior_facet_violations(points, flipped).max() <= DELAUNAY_GAIN
    assert check_valid_domain(Mesh(points, flipped)) == []
    assert np.array_equal(across, cell_neighbours(flipped))   # the neighbours kept up to date
    # the same cells as a new triangulation of the moved nodes (their hull is the box's, as before)
    assert np.array_equal(unique_rows(np.sort(flipped, axis=1))[0], unique_rows(np.sort(delaunay(points), axis=1))[0])


@pytest.mark.parametrize("dim, side", [(2, 30), (3, 12)])
def test_the_boundary_the_nodes_and_the_volume_stay(dim, side):
    points, cells = jittered_grid(dim, side, 3)
    flipped, _ = flip_to_delaunay(points, cells)
    assert np.array_equal(unique_rows(boundary_facets(flipped))[0], unique_rows(boundary_facets(cells))[0])
    assert np.array_equal(np.unique(flipped), np.arange(len(points)))
    assert signed_measures(points, flipped).sum() == pytest.approx(signed_measures(points, cells).sum(), rel=1e-12)
    assert signed_measures(points, flipped).min() > 0


def test_a_delaunay_triangulation_is_left_as_it_is():
    points, _ = jittered_grid(3, 10, 4)
    cells = delaunay(points)
    assert np.array_equal(flip_to_delaunay(points, cells)[0], cells)


def test_a_run_that_fills_its_room_goes_on_from_where_it_stopped():
    from bitemesh.core.optimize.delaunay_flips import _flip_in_room
    points, cells = jittered_grid(3, 10, 5)
    across = cell_neighbours(cells)
    partial, links, full, flips = _flip_in_room(points, cells, across, len(cells) + 2, 10 ** 6)
    assert full and len(partial) == len(cells) + 2 and 0 < flips   # two 2-3 flips more than 3-2 flips, then no room
    assert np.array_equal(links, cell_neighbours(partial)) and check_valid_domain(Mesh(points, partial)) == []
    finished, _ = flip_to_delaunay(points, partial, links)
    assert interior_facet_violations(points, finished).max() <= DELAUNAY_GAIN


def test_no_flip_makes_an_edge_the_mesh_already_has():
    """81 cells of the two-cavity heart's RV wall (about 3 R thick) after a relaxation move: every vertex on the
    boundary, the wall folded so that a 2-3 flip passes its own tests (non-Delaunay facet, positive new cells) but
    makes an edge that a cell already holds.  Made, it left a facet in three cells; the relaxation was then
    abandoned and the optimised heart kept 76 poor cells."""
    from pathlib import Path
    with np.load(Path(__file__).parent / "data" / "folded_wall.npz") as data:
        points, cells = data["points"], data["cells"]
    assert cell_neighbours(cells).min() >= -1   # the input: every facet in one or two cells
    flipped, across = flip_to_delaunay(points, cells)
    assert cell_neighbours(flipped).min() >= -1
    assert np.array_equal(across, cell_neighbours(flipped))
    assert np.array_equal(unique_rows(boundary_facets(flipped))[0], unique_rows(boundary_facets(cells))[0])
    assert signed_measures(points, flipped).sum() == pytest.approx(signed_measures(points, cells).sum(), rel=1e-12)
    assert signed_measures(points, flipped).min() > 0
