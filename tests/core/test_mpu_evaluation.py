"""The MPU implicit at grid nodes (pairs found from the grid) is bit-identical to its k-d tree evaluation."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from bitemesh.core import mpu_function
from bitemesh.core.grid import sample_function
from bitemesh.core.implicit import fit_mpu
from bitemesh.core.mpu_pairs import TreeOrder, lattice_pairs, traversal_keys

from .test_implicit import torus_sample


@pytest.fixture(scope="module")
def torus():
    points, normals = torus_sample(3000, seed=3)
    return fit_mpu(points, normals)


def grid_nodes(lower, upper, shape):
    """(x (m, 3), index, axes) of all nodes of a grid, C order, as grid.sample_function lays them."""
    axes = tuple(lower[d] + np.arange(n) * ((upper[d] - lower[d]) / (n - 1)) for d, n in enumerate(shape))
    index = np.unravel_index(np.arange(int(np.prod(shape))), shape)
    return np.stack([axes[d][index[d]] for d in range(3)], axis=1), index, axes


@pytest.mark.parametrize("block, chunk", [(1 << 16, 1 << 15), (997, 3001)])
def test_at_nodes_is_bit_identical_to_the_tree_evaluation(torus, monkeypatch, block, chunk):
    """Small pair blocks and evaluation chunks put many block boundaries inside the leaf groups."""
    monkeypatch.setattr(mpu_function, "_PAIR_BLOCK", block)
    monkeypatch.setattr(mpu_function, "_EVALUATION_CHUNK", chunk)
    x, index, axes = grid_nodes(torus.lower - 0.1, torus.upper + 0.1, (23, 25, 14))
    keep = np.flatnonzero(np.abs(torus(x)) < 0.3)   # a band, with gaps in its rows
    band = tuple(i[keep] for i in index)
    assert np.array_equal(torus.at_nodes(x[keep], band, axes), torus(x[keep]))
    assert np.array_equal(torus.at_nodes(x, index, axes), torus(x))


def test_lattice_pairs_are_the_tree_pairs_block_by_block(torus):
    x, index, axes = grid_nodes(torus.lower, torus.upper, (20, 20, 12))
    found = lattice_pairs(torus._lattice_groups, x, index, axes, 1000)
    expected = torus._tree_pairs(x)
    assert len(found[0]) == len(expected[0]) > 5000
    for start in range(0, len(found[0]), 1000):
        got, want = (tuple(column[start:start + 1000] for column in pairs) for pairs in (found, expected))
        for column in range(3):
            assert np.array_equal(np.sort(got[column]), np.sort(want[column]))
        for point in np.unique(want[1]):   # each point's pairs in the same order
            assert np.array_equal(got[0][got[1] == point], want[0][want[1] == point])


def test_nodes_out_of_c_order_fall_back_to_the_tree(torus):
    x, index, axes = grid_nodes(torus.lower, torus.upper, (9, 9, 6))
    flipped = np.arange(len(x))[::-1]
    assert lattice_pairs(torus._lattice_groups, x[flipped], tuple(i[flipped] for i in index), axes, 1000) is None
    assert np.array_equal(torus.at_nodes(x[flipped], tuple(i[flipped] for i in index), axes), torus(x[flipped]))


@pytest.mark.parametrize("seed", [0, 1])
def test_traversal_keys_sort_pairs_as_the_sparse_distance_matrix(seed):
    rng = np.random.default_rng(seed)
    first, second = cKDTree(rng.random((700, 3))), cKDTree(rng.random((2000, 3)) * [1, 2, 0.5])
    listed = first.sparse_distance_matrix(second, 0.2, output_type="ndarray")
    keys = traversal_keys(TreeOrder.of(first), TreeOrder.of(second), listed["i"], listed["j"])
    assert np.all(np.diff(keys) > 0)


def test_sample_function_uses_at_nodes_with_the_same_values(torus):
    lower, upper = torus.lower, torus.upper
    fast = sample_function(torus, lower, upper, 0.05, exact_within=0.15, levels=2)
    plain = sample_function(lambda x: torus(x), lower, upper, 0.05, exact_within=0.15, levels=2)
    assert np.array_equal(fast.values, plain.values)
