"""Shape modes of a cohort (core.fem.shape_modes): shapes built as a base plus two known modes with known standard
deviations, each turned and moved at random: the alignment undoes the motions, the two modes are found (the
subspace they span, to rounding), their variances' shares are the built ones, and the mean moved along a mode by
its weights gives the built shape back."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.shape_modes import shape_modes
from scipy.spatial.transform import Rotation


def cohort(count=40, seed=2):
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(60, 3)) * [3.0, 2.0, 1.0]
    modes = np.linalg.qr(rng.normal(size=(180, 2)))[0].T.reshape(2, 60, 3)
    # modes that are no rigid motion of the base (their projections on the 6 rigid directions removed)
    rigid = np.array([np.tile(axis, (60, 1)).ravel() for axis in np.eye(3)]
                     + [np.cross(axis, base - base.mean(axis=0)).ravel() for axis in np.eye(3)])
    basis = np.linalg.qr(rigid.T)[0]
    flat = modes.reshape(2, -1)
    flat -= (flat @ basis) @ basis.T
    modes = np.linalg.qr(flat.T)[0].T.reshape(2, 60, 3)
    weights = rng.normal(size=(count, 2)) * [2.0, 0.5]
    weights -= weights.mean(axis=0)
    shapes = base + np.einsum("ck,kni->cni", weights, modes)
    turns = Rotation.random(count, random_state=seed).as_matrix()
    moved = np.einsum("cij,cnj->cni", turns, shapes) + rng.normal(size=(count, 1, 3)) * 50
    return moved, modes @ turns[0].T, weights   # the modes as they lie in the first shape's frame


def test_two_built_modes_are_found_through_random_rigid_motions():
    """(The found modes lie in the first shape's frame, as the mean does.)"""
    shapes, modes, weights = cohort()
    found = shape_modes(shapes)
    assert len(found.modes) == 2
    # the modes span the built ones (up to the small rotation the mean of a varying cohort takes from the first)
    built = modes.reshape(2, -1)
    for mode in found.modes[:2].reshape(2, -1):
        assert np.linalg.norm(built @ mode) == pytest.approx(1.0, abs=1e-3)
    expected = weights.var(axis=0, ddof=1)
    assert found.explained[:2] == pytest.approx(expected / expected.sum(), abs=5e-3)
    assert found.explained[:2].sum() > 0.999
    assert found.deviations[0] == pytest.approx(np.sqrt(expected[0]), rel=1e-2)
    np.testing.assert_allclose(found.shape([2.0, -1.0]) - found.mean,
                               2 * found.deviations[0] * found.modes[0] - found.deviations[1] * found.modes[1])


def test_rigid_copies_have_no_mode_and_the_mean_is_the_shape():
    shapes, _, _ = cohort()
    turns = Rotation.from_euler("z", [[0.0], [10.0], [20.0], [30.0], [40.0]], degrees=True).as_matrix()
    copies = np.einsum("cij,nj->cni", turns, shapes[0])
    found = shape_modes(copies)
    assert len(found.modes) == 0
    np.testing.assert_allclose(found.mean, copies[0], atol=1e-9)


def test_too_few_shapes_are_refused():
    with pytest.raises(InvalidInputError, match="at least 2 meshes"):
        shape_modes(np.zeros((1, 10, 3)))
