"""Handles cut or filled where they are thinnest (bitemesh.core.steps.handles), on solid tori: the cheaper of a cut
across the tube and a fill across the hole is taken."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.core.steps.biting import bite
from bitemesh.core.steps.delaunay import delaunay
from bitemesh.core.steps.repair import carve_domain
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.steps.handles import handle_count
from bitemesh.core.parameters import SpuriousParameters

from tests.builders import volume
from tests.meshcheck import assert_valid_domain

#: lattice spacing of the nodes (the cells are about this size)
STEP = 0.25


def torus(major: float, minor: float):
    def f(x):
        ring = np.hypot(x[:, 0], x[:, 1]) - major
        return minor - np.hypot(ring, x[:, 2])
    return f


def carved(function, extent, handles: str):
    """The carved domain of ``function`` over [-extent, extent], nodes bitten at R = STEP."""
    lower, upper = -np.asarray(extent, float), np.asarray(extent, float)
    grid = sample_function(function, lower, upper, STEP / 4, margin=STEP)
    nodes = bite(grid, STEP, seed=0)
    return carve_domain(grid, nodes, delaunay(nodes), SpuriousParameters(handles=handles))


def tunnelled_ball(radius: float, hole: float):
    """A ball with a straight tunnel of radius ``hole`` along z."""
    return lambda x: np.minimum(radius - np.linalg.norm(x, axis=1), np.hypot(x[:, 0], x[:, 1]) - hole)


@pytest.mark.parametrize("function, extent, section, cut", [
    (torus(1.5, 0.35), (2.0, 2.0, 0.6), np.pi * 0.35**2, True),   # a ring thinner than two cells: cut across
    (tunnelled_ball(1.5, 0.2), (1.7, 1.7, 1.7), np.pi * 0.2**2, False),   # a tunnel that thin: filled
])
def test_a_handle_thinner_than_two_cells_is_cut_or_filled(function, extent, section, cut):
    """The change is about one layer of cells across the handle's section (thickness <= 3 x STEP)."""
    kept, removed = carved(function, extent, "keep"), carved(function, extent, "remove")
    assert_valid_domain(kept, euler=0, components=1)
    assert_valid_domain(removed, euler=2, components=1)
    assert handle_count(removed.cells) == 0
    change = volume(removed) - volume(kept)
    assert (change < 0) == cut and abs(change) <= 3 * STEP * section


@pytest.mark.parametrize("function, extent", [
    (torus(3.0, 1.0), (4.2, 4.2, 1.2)),   # a handle of the data: four cells thick
    (lambda x: 1.5 - np.linalg.norm(x, axis=1), (1.7, 1.7, 1.7)),   # no handle
])
def test_a_thick_handle_or_none_is_left_as_it_is(function, extent):
    kept, removed = carved(function, extent, "keep"), carved(function, extent, "remove")
    assert np.array_equal(kept.cells, removed.cells) and np.array_equal(kept.points, removed.points)
