"""The MeshOptimizer's pieces on hand-made configurations (no VTK): the sliver flips (2-3, 3-2, 2-2 in 2D, edge
removal), the peel, and the cell measures they decide by (the closed-form radius ratio, Knupp's mean ratio and its
gradient, the kernels' sums in numpy's order).  The whole step on analytic shapes:
tests/core/optimize/test_optimize.py."""
from __future__ import annotations

from math import comb

import numpy as np
import pytest

from bitemesh.core.optimize.measures import _lane_sum, inverse_mean_ratio, mean_ratio_cost, mean_ratio_terms
from bitemesh.core.mesh.quality import signed_radius_ratio
from bitemesh.core.steps.delaunay import delaunay
from bitemesh.core.optimize.flips import flip, polygon_triangulations
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.optimize.slivers import peel
from bitemesh.core.mesh.validity import check_valid_domain
from bitemesh.core.mesh.quality import radius_ratio

TRIANGLE = np.array([[1.0, 0.0, 0.0], [-0.5, np.sqrt(3) / 2, 0.0], [-0.5, -np.sqrt(3) / 2, 0.0]])


def bipyramid(height):
    """A triangle in z = 0 (nodes 0-2) and apexes below (3) and above (4) at ``height``."""
    return np.concatenate([TRIANGLE, [[0, 0, -height], [0, 0, height]]])


def test_a_2_3_flip_replaces_two_flat_cells():
    points = bipyramid(0.2)
    cells = np.array([[0, 1, 2, 4], [1, 0, 2, 3]])  # Q 0.11 each
    flipped = flip(points, cells)
    assert len(flipped) == 3 and (np.sort(flipped[:, :2], axis=1) == [3, 4]).all()
    assert signed_radius_ratio(points, flipped).min() == pytest.approx(0.398, abs=1e-3)
    assert check_valid_domain(Mesh(points, flipped)) == []


def test_a_3_2_flip_removes_a_long_edge():
    points = bipyramid(1.5)
    cells = np.array([[3, 4, 0, 1], [3, 4, 1, 2], [3, 4, 2, 0]])  # Q 0.35 each
    flipped = flip(points, cells)
    assert len(flipped) == 2 and signed_radius_ratio(points, flipped).min() > 0.99
    assert signed_measures(points, flipped).sum() == pytest.approx(signed_measures(points, cells).sum())
    assert check_valid_domain(Mesh(points, flipped)) == []


def test_a_good_pair_is_not_flipped():
    points = bipyramid(0.8)  # 2 cells Q 0.81 would become 3 of Q 0.73
    cells = np.array([[0, 1, 2, 4], [1, 0, 2, 3]])
    assert np.array_equal(flip(points, cells), cells)


def test_a_2d_edge_flip_takes_the_short_diagonal():
    points = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.5], [1.0, -0.5]])
    cells = np.array([[0, 1, 2], [1, 0, 3]])
    flipped = flip(points, cells)
    assert sorted(map(sorted, flipped.tolist())) == [[0, 2, 3], [1, 2, 3]]
    assert (signed_measures(points, flipped) > 0).all()


def test_peel_takes_a_flat_cell_off_the_surface_unless_that_leaves_a_node_unused():
    # a pyramid on a square (apex below, the square split along 0-2), and a flat cell on its top whose two upper
    # facets join along the raised diagonal 1-3
    points = np.array([[0, 0, 0], [1, 0, 0.05], [1, 1, 0], [0, 1, 0.05], [0.5, 0.5, -0.7]])
    cells = np.array([[0, 1, 2, 4], [0, 2, 3, 4], [0, 1, 2, 3]])
    negative = signed_measures(points, cells) < 0
    cells[negative, :2] = cells[negative, 1::-1]
    assert check_valid_domain(Mesh(points, cells)) == []
    assert radius_ratio(points, cells[2:]) < 0.2
    peeled = peel(cells, len(points), np.array([2]))
    assert np.array_equal(peeled, cells[:2]) and check_valid_domain(Mesh(points, peeled)) == []
    assert np.array_equal(peel(cells, len(points), np.array([0, 1])), cells)  # the apex would be left unused


def test_edge_removal_knows_every_triangulation_of_the_ring():
    for n in range(3, 8):
        triangles, triangulations = polygon_triangulations(n)
        assert len(triangles) == comb(n, 3)
        assert len(triangulations) == comb(2 * (n - 2), n - 2) // (n - 1)  # Catalan numbers 1, 2, 5, 14, 42
        assert len({tuple(sorted(t)) for t in triangulations.tolist()}) == len(triangulations)


@pytest.mark.parametrize("dim", [2, 3])
def test_the_closed_form_radius_ratio_agrees_with_its_definition(dim):
    """Q = k r_in / R_circ from the circumsphere and r_in = k |measure| / (sum of facet measures), against the
    closed form the quality arrays and the optimizer use; signed for inverted cells."""
    from bitemesh.core.mesh.simplicial import circumspheres
    from bitemesh.core.mesh.quality import facet_normals
    rng = np.random.default_rng(dim)
    points = rng.random((200, dim))
    cells = delaunay(points)
    surface = np.linalg.norm(facet_normals(points, cells), axis=-1).sum(axis=1)
    definition = dim * dim * np.abs(signed_measures(points, cells)) / (surface * circumspheres(points, cells)[1])
    assert np.allclose(signed_radius_ratio(points, cells), definition, atol=1e-12)
    assert np.allclose(radius_ratio(points, cells), definition, atol=1e-12)
    inverted = cells[:, [1, 0] + list(range(2, dim + 1))]
    assert np.allclose(signed_radius_ratio(points, inverted), -definition, atol=1e-12)


def test_the_kernels_sum_in_numpy_einsums_order():
    """The mean-ratio kernels sum in the order of numpy's einsum (cell_measures._lane_sum), so that the smoothing
    moves the nodes to the same bits as the vectorized code did; a numpy build that sums otherwise fails here."""
    rng = np.random.default_rng(0)
    for count in range(1, 20):
        a, b = rng.normal(size=(2, 50, count))
        expected = np.einsum("ij,ij->i", a, b)
        assert all(_lane_sum(a[i] * b[i], count) == expected[i] for i in range(50))


@pytest.mark.parametrize("dim", [2, 3])
def test_mean_ratio_is_one_on_the_regular_simplex_and_its_gradient_is_exact(dim):
    regular = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]]) if dim == 2 else \
        np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]])
    if signed_measures(regular, np.arange(dim + 1)[None])[0] < 0:
        regular = regular[[1, 0] + list(range(2, dim + 1))]
    cell = np.arange(dim + 1)[None]
    assert inverse_mean_ratio(regular, cell) == pytest.approx(1.0)
    assert inverse_mean_ratio(regular, cell[:, [1, 0] + list(range(2, dim + 1))])[0] == np.inf
    corners = regular[None] + np.random.default_rng(0).normal(0, 0.1, (1, dim + 1, dim))
    volume_, squares, volume_gradient, centred = mean_ratio_terms(corners[0], cell)
    cost = mean_ratio_cost(volume_, squares, dim)
    gradient = cost[:, None, None] * (2 * (dim + 1) * centred / squares[:, None, None]
                                      - (2 / dim) * volume_gradient / volume_[:, None, None])
    step = 1e-6
    for i in range(dim + 1):
        for d in range(dim):
            shifted = np.zeros_like(corners)
            shifted[0, i, d] = step
            numeric = (inverse_mean_ratio((corners + shifted)[0], cell)
                       - inverse_mean_ratio((corners - shifted)[0], cell)) / (2 * step)
            assert gradient[0, i, d] == pytest.approx(numeric[0], rel=1e-5)
