"""Invariants of the whole method (hypothesis): a rigid motion or a scaling of the input moves the mesh with it,
and the same input and seed give the same mesh bit for bit.

The shape is an ellipsoid with three different semi-axes (so that no symmetry hides a wrong axis), sampled with
its normals.  A rotation turns the grid I relative to the shape, so the nodes differ; what must not change is what
a user relies on: a valid domain, its volume (that of the unmoved mesh within 1 %: both lose about 3 % to the
chords of ~2,500 cells), its boundary on the surface (within R / 2: a boundary vertex that the carve exposes, not
one of the border layer projected onto f = 0, can lie up to half a node spacing off), the cell count (within 10 %)
and the fidelity (no far sample).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.sources.points import run
from bitemesh.core.shapes import sample_surface
from bitemesh.core.mesh.topology import boundary_facets
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.builders import ELLIPSOID_AXES, ellipsoid
from tests.meshcheck import assert_valid_domain

AXES = ELLIPSOID_AXES
VOLUME = ellipsoid().measure
CELLS = 2500


def ellipsoid_samples():
    return sample_surface(ellipsoid(), spacing=0.06, seed=3)


SAMPLES = ellipsoid_samples()
REFERENCE = run(*SAMPLES, biting=BitingParameters(cells=CELLS))


def rotation_from(quaternion) -> np.ndarray:
    w, x, y, z = np.asarray(quaternion, float) / np.linalg.norm(quaternion)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def ellipsoid_level(points: np.ndarray) -> np.ndarray:
    """|x/a|^2 + ... - 1 scaled to about a distance: 0 on the surface."""
    return (np.sqrt(np.sum((points / AXES) ** 2, axis=1)) - 1) * AXES.min()


quaternions = st.tuples(*[st.floats(-1, 1) for _ in range(4)]).filter(lambda q: np.linalg.norm(q) > 0.1)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(quaternion=quaternions, offset=st.floats(-1e7, 1e7), direction=st.integers(0, 2),
       log_scale=st.floats(-6, 6))
def test_a_rigid_motion_and_a_scaling_move_the_mesh_with_them(quaternion, offset, direction, log_scale):
    turn, scale = rotation_from(quaternion), 10.0 ** log_scale
    shift = np.zeros(3)
    shift[direction] = offset
    points, normals = SAMPLES
    result = run(points @ turn.T * scale + shift, normals @ turn.T, biting=BitingParameters(cells=CELLS))
    mesh = result.mesh
    reference = float(REFERENCE.mesh.cell_data["Volume"].sum())
    assert_valid_domain(mesh, measure=reference * scale**3, measure_tolerance=0.01)
    assert abs(len(mesh.cells) / len(REFERENCE.mesh.cells) - 1) < 0.1
    assert result.radius / scale == pytest.approx(REFERENCE.radius, rel=0.05)
    back = (mesh.points[np.unique(boundary_facets(mesh.cells))] - shift) / scale @ turn
    assert np.abs(ellipsoid_level(back)).max() < 0.5 * REFERENCE.radius
    assert result.fidelity.far_samples == 0


@settings(max_examples=4, deadline=None)
@given(offset=st.sampled_from([0.0, 123.456, -7e6]), seed=st.integers(0, 2**32 - 1))
def test_the_same_input_and_seed_give_the_same_mesh(offset, seed):
    points, normals = SAMPLES
    first = run(points + offset, normals, biting=BitingParameters(cells=1500, seed=seed)).mesh
    second = run(points + offset, normals, biting=BitingParameters(cells=1500, seed=seed)).mesh
    np.testing.assert_array_equal(first.points, second.points)
    np.testing.assert_array_equal(first.cells, second.cells)


@settings(max_examples=3, deadline=None)
@given(repeats=st.integers(2, 5), log_scale=st.floats(-4, 4), seed=st.integers(0, 2**32 - 1))
def test_merged_scans_give_the_mesh_of_one_scan(repeats, log_scale, seed):
    """Every sample repeated up to 5 times, each copy after the first moved by 1e-9 of the size (scans merged from
    several passes), at any scale: the copies are merged into the first, and the mesh is that of one scan, bit for
    bit."""
    points, normals = SAMPLES
    scale = 10.0 ** log_scale
    jitter = np.random.default_rng(seed).normal(scale=1e-9 * scale, size=(len(points) * repeats, 3))
    jitter[::repeats] = 0.0   # the first copy of each sample is the sample
    merged = run(np.repeat(points * scale, repeats, axis=0) + jitter, np.repeat(normals, repeats, axis=0),
                 biting=BitingParameters(cells=CELLS))
    alone = run(points * scale, normals, biting=BitingParameters(cells=CELLS))
    np.testing.assert_array_equal(merged.mesh.cells, alone.mesh.cells)
    np.testing.assert_array_equal(merged.mesh.points, alone.mesh.points)
    assert any("near-duplicate" in note for note in merged.notes)


@settings(max_examples=3, deadline=None)
@given(coarser=st.floats(1.0, 4.0), seed=st.integers(0, 2**16))
def test_a_half_sampled_more_sparsely_meshes_the_whole_shape(coarser, seed):
    """One half of the ellipsoid sampled up to 4 x more coarsely (16 x fewer points) than the other: no sample is
    dropped as an outlier, and the mesh is the whole ellipsoid (valid, its volume that of the evenly sampled one
    within 2 %, no far sample)."""
    sparse, sparse_normals = sample_surface(ellipsoid(), spacing=0.06 * coarser, seed=seed)
    points, normals = SAMPLES
    upper, lower = points[:, 2] > 0, sparse[:, 2] <= 0
    result = run(np.vstack([points[upper], sparse[lower]]), np.vstack([normals[upper], sparse_normals[lower]]),
                 biting=BitingParameters(cells=CELLS))
    reference = float(REFERENCE.mesh.cell_data["Volume"].sum())
    assert_valid_domain(result.mesh, euler=2, components=1, measure=reference, measure_tolerance=0.02)
    assert not any("outliers" in note for note in result.notes) and result.fidelity.far_samples == 0
