"""The grid I kept by the band (issue 12, memory by the bit): a BandedGrid answers every question the steps ask
exactly as the grid with every node kept would, while its memory follows the surface."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from bitemesh.core.steps.biting import _sort_into
from bitemesh.core.grid.sampled import BRICK, BandedGrid, ImplicitGrid, sample_function
from bitemesh.core.shapes import sphere, torus


def wavy(x):
    """f > 0 inside a wavy ellipsoid (2D: ellipse), about a signed distance."""
    return 0.8 - np.linalg.norm(x * [1.0, 1.3, 0.7][:x.shape[1]], axis=1) + 0.05 * np.sin(7 * x[:, 0])


def refined(values):
    """Every cell halved, the new nodes the mean of their two neighbours, axis after axis (the reference)."""
    for axis in range(values.ndim):
        moved = np.moveaxis(values, axis, 0)
        finer = np.empty((2 * len(moved) - 1, *moved.shape[1:]))
        finer[::2], finer[1::2] = moved, 0.5 * (moved[:-1] + moved[1:])
        values = np.moveaxis(finer, 0, axis)
    return values


def both(dim, levels=1, spacing=0.03):
    """The wavy shape on one grid twice: every node sampled, and exactly only within 3 spacings of f = 0."""
    lower, upper = -np.ones(dim), np.ones(dim)
    band = sample_function(wavy, lower, upper, spacing, margin=0.1, exact_within=3 * spacing, levels=levels)
    # the dense twin: the same coarse grid refined, the band's nodes evaluated: what the banded one must equal
    return band, sample_function(wavy, lower, upper, spacing, margin=0.1)


@pytest.mark.parametrize("dim, levels", [(3, 1), (3, 2), (2, 1), (2, 2)])
def test_a_banded_grid_answers_as_its_dense_values_do(dim, levels):
    band, _ = both(dim, levels)
    assert isinstance(band, BandedGrid)
    dense = ImplicitGrid(band.origin, band.spacing, band.values)   # every node of the banded grid, kept
    rng = np.random.default_rng(1)
    points = rng.uniform(-1.3, 1.3, (5000, dim))   # inside and beyond the grid
    points[:3] = np.nan
    assert np.array_equal(band.evaluate(points), dense.evaluate(points), equal_nan=True)
    assert np.array_equal(band.gradient(points), dense.gradient(points), equal_nan=True)
    assert np.array_equal(band.inside(), dense.values > 0)
    assert band.inside_volume() == dense.inside_volume()
    flat = rng.integers(0, band.values.size, 1000)
    assert np.array_equal(band.node_values(flat), dense.values.ravel()[flat])


@pytest.mark.parametrize("dim", [3, 2])
def test_the_dense_grid_interpolates_as_scipy_and_numpy_do(dim):
    """The kernels' arithmetic is map_coordinates' (order 1, mode nearest) of f and of numpy.gradient's grids, bit
    for bit, NaN for NaN."""
    from scipy.ndimage import map_coordinates
    _, dense = both(dim)
    points = np.random.default_rng(2).uniform(-1.3, 1.3, (3000, dim))
    points[0] = np.nan
    index = ((points - dense.origin) / dense.spacing).T
    inside = np.all((points >= dense.origin) & (points <= dense.upper), axis=1)
    expected = map_coordinates(dense.values, index, order=1, mode="nearest")
    assert np.array_equal(dense.evaluate(points)[inside], expected[inside])
    # beyond the grid (up to 3 box sizes away): at most minus the distance to its box, the nearest node's value
    # where that is lower
    far = np.random.default_rng(3).uniform(-4.0, 4.0, (3000, dim))
    nearest = map_coordinates(dense.values, ((far - dense.origin) / dense.spacing).T, order=1, mode="nearest")
    distance = np.linalg.norm(np.maximum(dense.origin - far, 0) + np.maximum(far - dense.upper, 0), axis=1)
    beyond = distance > 0
    assert (beyond & (-distance < nearest)).sum() > 100 and (beyond & (-distance > nearest)).sum() > 100
    assert np.array_equal(dense.evaluate(far), np.where(beyond, np.minimum(nearest, -distance), nearest))
    for axis, component in enumerate(np.gradient(dense.values, *dense.spacing)):
        expected = map_coordinates(component, index, order=1, mode="nearest")
        assert np.array_equal(dense.gradient(points)[:, axis], expected, equal_nan=True)


@pytest.mark.parametrize("dim", [3, 2])
def test_the_band_is_exact_near_the_surface_and_keeps_the_sign_everywhere(dim):
    band, dense = both(dim)
    near = np.abs(dense.values) < 2.5 * 0.03
    assert np.array_equal(band.values[near], dense.values[near])
    assert np.array_equal(band.inside(), dense.values > 0)
    # elsewhere the coarse grid's refinement: its interpolation error, a fraction of the spacing
    assert np.abs(band.values - dense.values).max() < 2 * 0.03
    coarse = sample_function(wavy, band.origin, band.origin + (np.array(band.coarse.shape[:dim]) - 1) * 0.06, 0.06)
    refinement = refined(coarse.values)[tuple(slice(n) for n in band.shape)]
    far = np.abs(refinement) >= 3 * 0.03   # where the band is decided: on the refinement of the coarse grid
    assert np.array_equal(refinement[far], band.values[far]) and np.array_equal(dense.values[~far], band.values[~far])


def test_its_memory_follows_the_surface():
    """A sphere of radius 1 at spacing h: the bricks kept cover the band |f| < 3 h around the sphere, about
    4 pi (BRICK h)^-2 x 2 bricks of BRICK^3 nodes (the band is under one brick thick and meets two across), and the
    coarse grid holds 1/8 of the nodes.  Halving h multiplies the nodes by 8 and the bricks' nodes by about 4."""
    shape = sphere()
    kept = []
    for spacing in (0.02, 0.01):
        grid = sample_function(shape.function, shape.lower, shape.upper, spacing, margin=3 * spacing,
                               exact_within=3 * spacing)
        nodes = np.prod(grid.shape)
        assert grid.coarse.size == pytest.approx(nodes / 8, rel=0.05)
        bricks = grid.bricks.shape[0]
        assert bricks <= 3 * 4 * np.pi / (BRICK * spacing) ** 2
        kept.append(grid.bricks.size / nodes)
    assert kept[1] < 0.6 * kept[0]   # the surface's share of the nodes halves with h (measured: 0.50)
    # 8 bytes a node would be every node kept; here 1/8 (the coarse grid) + the bricks' share (0.23, halving with h)
    assert grid.bricks.nbytes + grid.coarse.nbytes < 0.4 * 8 * nodes


def test_scaled_moves_and_scales_the_grid_and_f():
    band, _ = both(3)
    origin = np.array([10.0, 20.0, 30.0])
    moved = band.scaled(origin, 2.0)
    assert isinstance(moved, BandedGrid) and moved.shape == band.shape
    points = np.random.default_rng(3).uniform(-0.9, 0.9, (500, 3))
    np.testing.assert_allclose(moved.evaluate(origin + 2 * (points - band.origin)), 2 * band.evaluate(points),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(moved.values, 2 * band.values, rtol=0, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 5), min_size=1, max_size=300), st.integers(0, 2**31))
def test_the_biting_order_is_lexsorts(keys, seed):
    """Keys with many ties (as f has where it is clamped), ties by a random draw, then by position."""
    key = np.array(keys, dtype=float)
    tie = np.random.default_rng(seed).integers(0, 3, key.size).astype(float)   # ties among the ties too
    items = np.arange(key.size) * 7 + 3
    out = np.empty_like(items)
    _sort_into(out, items, key, tie)
    assert np.array_equal(out, items[np.lexsort((tie, key))])


def test_a_torus_bites_the_same_from_either_grid():
    from bitemesh.core.steps.biting import bite
    shape = torus()
    band = sample_function(shape.function, shape.lower, shape.upper, 0.04, margin=0.12, exact_within=0.12)
    dense = ImplicitGrid(band.origin, band.spacing, band.values)
    assert np.array_equal(bite(band, 0.16, seed=3), bite(dense, 0.16, seed=3))
