"""Biting (the paper's Algorithm 1): spacing, coverage, boundary nodes on f = 0, determinism, bad radii."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from bitemesh.core.steps.biting import _sort_into, bite
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.shapes import annulus, sphere, torus

from tests.builders import sampled


@pytest.mark.parametrize("shape", [sphere(), torus(), annulus()], ids=lambda s: s.name)
def test_nodes_are_spaced_cover_the_domain_and_sit_on_the_surface(shape):
    radius = 0.15
    grid = sampled(shape, radius / 4)
    nodes = bite(grid, radius, seed=3)
    assert nodes.shape[1] == shape.dim
    tree = cKDTree(nodes)
    spacing = np.max(grid.spacing)
    nearest = tree.query(nodes, k=2)[0][:, 1]
    # KillNodes removes every Alive node within R; jitter and projection move nodes by about a grid spacing.
    assert nearest.min() >= radius - 2.5 * spacing
    inside = grid.node_coordinates(np.flatnonzero(grid.values > 0))
    assert tree.query(inside)[0].max() <= radius + spacing
    values = shape.function(nodes)
    # f on the grid is multilinear: the projected nodes sit on its zero set, within O(h^2 curvature) of the shape.
    assert values.min() >= -0.01 * radius
    on_surface = np.abs(values) < 0.01 * radius
    assert on_surface.sum() > 0.2 * len(nodes)


def test_same_seed_same_nodes_other_seed_other_nodes():
    grid = sampled(sphere(), 0.05)
    first, again, other = bite(grid, 0.2, seed=7), bite(grid, 0.2, seed=7), bite(grid, 0.2, seed=8)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)


def test_random_order_also_covers_the_domain():
    grid = sampled(sphere(), 0.05)
    nodes = bite(grid, 0.2, order="random", seed=1)
    inside = grid.node_coordinates(np.flatnonzero(grid.values > 0))
    assert cKDTree(nodes).query(inside)[0].max() <= 0.2 + 0.05


@pytest.mark.parametrize("radius, words", [(0.0, "radius"), (-1.0, "radius"), (0.05, "2 x grid_spacing"),
                                           (5.0, "radius"), (float("nan"), "radius")])
def test_bad_radius_names_the_parameter_and_the_range(radius, words):
    grid = sampled(sphere(), 0.05)
    with pytest.raises(InvalidInputError, match="radius") as error:
        bite(grid, radius)
    assert words in str(error.value)


def test_nothing_inside_is_a_clear_error():
    grid = sample_function(lambda p: -np.ones(len(p)), (0, 0, 0), (1, 1, 1), 0.1)
    with pytest.raises(InvalidInputError, match="positive nowhere"):
        bite(grid, 0.3)


def test_bad_order_names_the_choices():
    with pytest.raises(InvalidInputError, match="order must be one of"):
        bite(sampled(sphere(), 0.05), 0.2, order="spiral")


def test_sampling_exactly_only_near_the_surface_keeps_f_there_and_its_sign_everywhere():
    shape = torus()
    exact = sample_function(shape.function, shape.lower, shape.upper, 0.03, margin=0.1)
    banded = sample_function(shape.function, shape.lower, shape.upper, 0.03, margin=0.1, exact_within=0.09)
    near = np.abs(exact.values) < 0.075
    assert np.array_equal(exact.values[near], banded.values[near])
    assert np.array_equal(exact.values > 0, banded.values > 0)
    assert np.abs(exact.values - banded.values).max() < 2 * 0.03  # interpolation error of the coarse grid


@settings(max_examples=30, deadline=None)
@given(size=st.integers(1, 2000), distinct=st.integers(1, 50), equal_ties=st.booleans(), seed=st.integers(0, 2**16))
def test_the_selection_sort_is_numpys_lexsort_by_key_then_tie_then_position(size, distinct, equal_ties, seed):
    """The biting's order: by key (f or the distance), equal keys by the seeded tie, then by position."""
    rng = np.random.default_rng(seed)
    key = rng.integers(0, distinct, size).astype(float)
    tie = np.where(rng.random(size) < 0.3, 0.5, rng.random(size)) if equal_ties else rng.random(size)
    items = np.arange(size) * 7
    out = np.empty_like(items)
    _sort_into(out, items, key, tie)
    assert np.array_equal(out, items[np.lexsort((np.arange(size), tie, key))])
