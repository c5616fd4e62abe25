"""The whole method from scattered points: valid meshes of known shapes, determinism, and bad input."""
from __future__ import annotations

import numpy as np
import pytest

from bitemesh.core.errors import InvalidInputError
import bitemesh
from bitemesh.core.sources.points import run
from bitemesh.core.steps.spine import radius_for_cells
from bitemesh.core.shapes import annulus, die, sample_surface, sphere, torus, two_cavity_shell
from tests.meshcheck import assert_valid_domain


@pytest.fixture(scope="module")
def samples():
    """Noisy scattered points (0.1 % of the size) with their exact normals, per shape."""
    shapes = {shape.name: shape for shape in (sphere(), torus(), die(), two_cavity_shell())}
    return {name: (shape, *sample_surface(shape, 0.04, noise=0.002, seed=1)) for name, shape in shapes.items()}


@pytest.mark.parametrize("name", ["sphere", "torus", "die", "two-cavity shell"])
@pytest.mark.parametrize("with_normals", [True, False], ids=["normals", "estimated-normals"])
def test_scattered_points_give_a_valid_mesh_of_the_shape(samples, name, with_normals):
    shape, points, normals = samples[name]
    # the default (optimised) with the normals given; the plain method where the normals are estimated (what
    # differs is the fit's input: the optimizer would only add time)
    mesh = bitemesh.mesh(bitemesh.Samples(points, normals if with_normals else None), cells=20000,
                         optimize=int(with_normals)).mesh
    assert_valid_domain(mesh, euler=shape.boundary_euler, components=1, measure=shape.measure,
                        measure_tolerance=0.02, mean_quality=0.78)
    assert 0.75 * 20000 < len(mesh.cells) < 1.25 * 20000
    # boundary nodes lie on the true surface, within a small fraction of the node spacing; near the die's pips
    # (smaller than the spacing) and the shell's sharp rim the smooth implicit surface departs from the true one
    from bitemesh.core.mesh.topology import boundary_facets
    on_boundary = np.unique(boundary_facets(mesh.cells))
    spacing = np.median(np.linalg.norm(np.diff(mesh.points[mesh.cells[:, :2]], axis=1)[:, 0], axis=1))
    distance = np.abs(shape.function(mesh.points[on_boundary])) / spacing
    assert np.median(distance) < 0.02
    assert distance.max() < (0.25 if name in ("sphere", "torus") else 1.5)
    assert set(mesh.cell_data) == {"RadiusRatio", "MinDihedralAngle", "MaxDihedralAngle", "Volume", "Region"}


def test_a_2d_shape_with_a_hole_gives_valid_triangles():
    shape = annulus()
    points, normals = sample_surface(shape, 0.02, seed=2)
    mesh = bitemesh.mesh(bitemesh.Samples(points, normals), method="rbf", cells=3000).mesh
    assert mesh.cells.shape[1] == 3
    assert_valid_domain(mesh, measure=shape.measure, measure_tolerance=0.02, mean_quality=0.85)
    from bitemesh.core.mesh.validity import count_boundary_components
    assert count_boundary_components(mesh) == 2


def test_same_seed_same_mesh_and_another_seed_another_mesh(samples):
    _, points, normals = samples["torus"]
    first = bitemesh.mesh(bitemesh.Samples(points, normals), cells=3000, seed=11).mesh
    again = bitemesh.mesh(bitemesh.Samples(points, normals), cells=3000, seed=11).mesh
    other = bitemesh.mesh(bitemesh.Samples(points, normals), cells=3000, seed=12).mesh
    assert np.array_equal(first.points, again.points) and np.array_equal(first.cells, again.cells)
    assert not (len(first.points) == len(other.points) and np.array_equal(first.points, other.points))


def test_radius_sets_the_node_spacing(samples):
    _, points, normals = samples["sphere"]
    result = run(points, normals, biting=__import__("bitemesh.core.parameters", fromlist=["x"]).BitingParameters(
        radius=0.2))
    from bitemesh.core.mesh.quality import edge_lengths
    _, lengths = edge_lengths(result.mesh.points, result.mesh.cells)
    assert result.radius == 0.2
    assert 0.2 * 0.9 < np.median(lengths) < 0.2 * 1.6
    assert radius_for_cells(4 / 3 * np.pi, len(result.mesh.cells), 3) == pytest.approx(0.2, rel=0.1)


def test_the_input_points_are_not_modified(samples):
    _, points, normals = samples["sphere"]
    points_copy, normals_copy = points.copy(), normals.copy()
    bitemesh.mesh(bitemesh.Samples(points, normals), cells=1000)
    assert np.array_equal(points, points_copy) and np.array_equal(normals, normals_copy)


def test_duplicated_points_do_not_change_the_mesh(samples):
    _, points, normals = samples["sphere"]
    once = bitemesh.mesh(bitemesh.Samples(points, normals), cells=1000).mesh
    twice = bitemesh.mesh(bitemesh.Samples(np.concatenate([points, points]), np.concatenate([normals, normals])),
                          cells=1000).mesh
    assert np.array_equal(once.cells, twice.cells)


BAD_INPUT = {
    "empty": (np.zeros((0, 3)), {}, "points"),
    "three points": (np.eye(3), {}, "points"),
    "nan": (np.where(np.arange(300)[:, None] == 7, np.nan, np.random.default_rng(0).random((300, 3))), {}, "NaN"),
    "coplanar": (np.c_[np.random.default_rng(0).random((300, 2)), np.zeros(300)], {}, "points"),
    "wrong shape": (np.zeros((10, 4)), {}, "points"),
    "radius zero": (None, {"radius": 0.0}, "radius"),
    "radius negative": (None, {"radius": -1.0}, "radius"),
    "radius larger than the shape": (None, {"radius": 5.0}, "radius"),
    "radius too small for the grid": (None, {"radius": 0.01, "grid_spacing": 0.05}, "radius"),
    "grid too large for memory": (None, {"grid_spacing": 0.001, "max_memory_mb": 64}, "grid_spacing"),
    "threshold": (None, {"threshold": 1.5}, "threshold"),
    "method": (None, {"method": "marching"}, "method"),
    "cells": (None, {"cells": 0}, "cells"),
    "seed": (None, {"seed": -3}, "seed"),
}


@pytest.mark.parametrize("case", list(BAD_INPUT))
def test_bad_input_is_a_clear_error_naming_the_parameter(samples, case):
    points, parameters, words = BAD_INPUT[case]
    _, sphere_points, sphere_normals = samples["sphere"]
    normals = sphere_normals if points is None else None
    points = sphere_points if points is None else points
    with pytest.raises(InvalidInputError, match=words):
        bitemesh.mesh(bitemesh.Samples(points, normals), **parameters)


def test_normals_of_the_wrong_shape_are_refused(samples):
    _, points, normals = samples["sphere"]
    with pytest.raises(InvalidInputError, match="normals"):
        bitemesh.mesh(bitemesh.Samples(points, normals[:-1]))


def test_the_optimizer_switch_is_a_field_and_off_with_bounds_says_so(samples):
    """``optimize`` is OptimizeParameters' first field, on by default (issue 12: FEM-grade by default), and
    bitemesh.mesh takes it by name; bounds given with the switch off do nothing and say so; a misspelt keyword
    is refused with the closest name."""
    from dataclasses import fields

    from bitemesh.core.errors import BitemeshWarning
    from bitemesh.core.parameters import OptimizeParameters
    _, points, normals = samples["sphere"]
    assert fields(OptimizeParameters)[0].name == "optimize" and OptimizeParameters().optimize == 1
    default = run(points, normals).mesh
    plain = bitemesh.mesh(bitemesh.Samples(points, normals), optimize=0).mesh
    assert default.cell_data["MinDihedralAngle"].min() >= 20 > plain.cell_data["MinDihedralAngle"].min() + 5
    with pytest.warns(BitemeshWarning, match="optimize=0: the MeshOptimizer does not run"):
        bounds = run(points, normals, optimize=OptimizeParameters(optimize=0, min_dihedral=25.0)).mesh
    assert np.array_equal(bounds.points, plain.points) and np.array_equal(bounds.cells, plain.cells)
    with pytest.raises(InvalidInputError, match="'optimise' is not an option of bitemesh mesh; did you "
                                                "mean optimize"):
        bitemesh.mesh(bitemesh.Samples(points, normals), optimise=1)
    with pytest.raises(InvalidInputError, match="optimize must be in"):
        bitemesh.mesh(bitemesh.Samples(points, normals), optimize=2)
