"""The optimiser's warning when it cannot meet its bounds says where the poor cells lie, with the hint that works
there: a cell flat against one side of the surface (the surface triangulation folds; another seed) or a cell
across a wall a few cells thick (lower radius).  Hand-made single slivers on a slab f = h - |z|."""
from __future__ import annotations

import numpy as np
import pytest

from bitemesh.core.errors import BitemeshWarning
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.optimize.optimizer import warn_missed_bounds
from bitemesh.core.parameters import OptimizeParameters
from bitemesh.core.mesh.quality import dihedral_angles

from tests.builders import sampled


def slab(half_thickness):
    from bitemesh.core.shapes import Shape
    return Shape("slab", lambda p: half_thickness - np.abs(p[:, 2]), (-1.0, -1.0, -half_thickness),
                 (2.0, 2.0, half_thickness), 9.0 * 2 * half_thickness, 2)


def sliver(points):
    """One positively oriented cell on ``points`` (4, 3), checked to be a sliver (an angle below 20 degrees)."""
    points, cells = np.asarray(points, float), np.array([[0, 1, 2, 3]])
    if signed_measures(points, cells)[0] < 0:
        cells = cells[:, [1, 0, 2, 3]]
    mesh = Mesh(points, cells)
    assert dihedral_angles(mesh.points, mesh.cells).min() < 20
    return mesh


def warning_for(grid, mesh):
    with pytest.warns(BitemeshWarning) as caught:
        warn_missed_bounds(grid, mesh, OptimizeParameters(), 1)
    message, = [str(warning.message) for warning in caught]
    assert "1 of 1 cells remain below min_dihedral = 20 degrees" in message
    return message


def test_a_cell_flat_against_one_side_of_the_surface_is_a_fold_and_another_seed_is_the_hint():
    """Four nodes on the top face z = 0.5 (the fourth just under it): every node's normal is +z."""
    grid = sampled(slab(0.5), 0.05)
    mesh = sliver([[0, 0, 0.5], [1, 0, 0.5], [0, 1, 0.5], [0.3, 0.3, 0.48]])
    message = warning_for(grid, mesh)
    assert "1 lies flat against the surface" in message and "another seed" in message
    assert "elsewhere" not in message


def test_a_cell_across_a_thin_wall_has_the_radius_as_its_hint():
    """Two nodes on each face of a wall 0.1 thick: their normals oppose."""
    grid = sampled(slab(0.05), 0.01)
    mesh = sliver([[0, 0, 0.05], [1, 0, 0.05], [0, 1, -0.05], [1, 1, -0.05]])
    message = warning_for(grid, mesh)
    assert "1 lies elsewhere: across walls only a few cells thick" in message and "lower radius" in message
    assert "flat against" not in message
