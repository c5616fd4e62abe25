"""The elastic template (core.fem.template): a mesh moved onto new data with the same cells, on analytic cases
with a known answer: a rigid motion and scaling recovered exactly, a sphere sheared into an ellipsoid with its
nodes on the ellipsoid, the same answer twice, bad arguments named."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError, MeshingError
from bitemesh.core.fem.template import check_follows, fit_template
from bitemesh.core.mesh.quality import quality_summary
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.shapes import sample_surface, sphere
from bitemesh.core.sources.points import run

from tests.builders import ELLIPSOID_AXES, ellipsoid

AXES = ELLIPSOID_AXES   # three different axes: no symmetry but the four half turns
SHEAR = np.array([[1.3, 0.2, 0.0], [0.0, 0.9, 0.0], [0.0, 0.0, 0.7]])


@pytest.fixture(scope="module")
def ellipsoid_template():
    return run(*sample_surface(ellipsoid(), spacing=0.04, seed=3), biting=BitingParameters(cells=3000)).mesh


@pytest.fixture(scope="module")
def sphere_template():
    points, normals = sample_surface(sphere(), 0.04, seed=1)
    result = run(points, normals, biting=BitingParameters(cells=3000))
    return result.mesh, result.radius, points


def test_a_rigid_motion_and_scaling_is_recovered_exactly(ellipsoid_template):
    """The template's own boundary turned 40 degrees, scaled 2.5 x and moved far: the fit is that motion, to
    rounding, in one elastic round that moves nothing."""
    turn = np.array([[np.cos(0.7), -np.sin(0.7), 0.0], [np.sin(0.7), np.cos(0.7), 0.0], [0.0, 0.0, 1.0]])
    moved = 2.5 * ellipsoid_template.points @ turn.T + [10.0, 20.0, -30.0]
    fit = fit_template(ellipsoid_template, moved[np.unique(boundary_facets(ellipsoid_template.cells))])
    np.testing.assert_allclose(fit.mesh.points, moved, rtol=0, atol=1e-9)
    assert fit.similarity[0] == pytest.approx(2.5, rel=1e-12) and fit.rounds == 1
    np.testing.assert_array_equal(fit.mesh.cells, ellipsoid_template.cells)


def test_a_sphere_sheared_into_an_ellipsoid_lands_on_it(sphere_template):
    """Samples of the unit sphere sheared by a matrix with axes 1.3, 0.9, 0.7 and moved: every boundary node of the
    fitted sphere mesh within 0.05 R of the sheared surface, no cell inverted, the cells still FEM-grade (smallest
    dihedral angle >= 10 degrees), the data within R of the boundary."""
    mesh, radius, samples = sphere_template
    shift = np.array([5.0, -2.0, 1.0])
    fit = fit_template(mesh, samples @ SHEAR.T + shift)
    boundary = np.unique(boundary_facets(fit.mesh.cells))
    back = np.linalg.solve(SHEAR, (fit.mesh.points[boundary] - shift).T).T
    # |back| - 1 is a distance on the unit sphere; through the shear at most 1.3 x that on the ellipsoid
    assert 1.3 * np.abs(np.linalg.norm(back, axis=1) - 1).max() < 0.05 * radius
    assert signed_measures(fit.mesh.points, fit.mesh.cells).min() > 0
    assert quality_summary(fit.mesh).angle_min >= 10.0
    assert fit.distances.max() < radius
    np.testing.assert_array_equal(fit.mesh.cells, mesh.cells)


def test_the_same_template_and_data_give_the_same_mesh(sphere_template):
    mesh, _, samples = sphere_template
    first, second = (fit_template(mesh, samples * [1.2, 1.0, 0.8]) for _ in range(2))
    np.testing.assert_array_equal(first.mesh.points, second.mesh.points)


@pytest.mark.parametrize("change, words", [
    ({"pull": 0.0}, "pull must be in"),
    ({"rounds": 0}, "rounds must be in"),
    ({"data": np.zeros((3, 3))}, "at least 4 points"),
    ({"template": Mesh(np.array([[0.0, 0], [1, 0], [0, 1]]), np.array([[0, 1, 2]]))}, "tetrahedral mesh"),
])
def test_bad_arguments_are_named(sphere_template, change, words):
    mesh, _, samples = sphere_template
    arguments = {"template": mesh, "data": samples, **change}
    with pytest.raises(InvalidInputError, match=words):
        fit_template(arguments.pop("template"), arguments.pop("data"), **arguments)


def test_data_by_surface_pulls_each_surface_to_its_own(sphere_template):
    """Data given by the template's tag names: the sphere's one boundary tag with the sheared samples fits as the
    whole-boundary array does; a name that is no tag is refused, listing the tags."""
    mesh, _, samples = sphere_template
    (name,) = [tag for tag, (_, dim) in mesh.tag_names.items() if dim == 2]
    by_name = fit_template(mesh, {name: samples @ SHEAR.T})
    whole = fit_template(mesh, samples @ SHEAR.T)
    np.testing.assert_array_equal(by_name.mesh.points, whole.mesh.points)
    with pytest.raises(InvalidInputError, match=rf"'LV_ENDO' is no surface of the template; its surfaces are .*{name}"):
        fit_template(mesh, {"LV_ENDO": samples})


def test_fibres_of_a_rotated_template_rotate_with_it(ellipsoid_template):
    """Orthonormal Fibre / Sheet / SheetNormal on every cell, the template turned and moved: each cell's vectors are
    the turned ones, to rounding (the deformation gradient of a rotation is the rotation)."""
    rng = np.random.default_rng(5)
    fibre = rng.normal(size=(len(ellipsoid_template.cells), 3))
    fibre /= np.linalg.norm(fibre, axis=1, keepdims=True)
    sheet = np.cross(fibre, rng.normal(size=fibre.shape))
    sheet /= np.linalg.norm(sheet, axis=1, keepdims=True)
    template = Mesh(ellipsoid_template.points, ellipsoid_template.cells,
                    {"Fibre": fibre, "Sheet": sheet, "SheetNormal": np.cross(fibre, sheet)})
    turn = np.array([[np.cos(1.1), 0.0, np.sin(1.1)], [0.0, 1.0, 0.0], [-np.sin(1.1), 0.0, np.cos(1.1)]])
    moved = template.points @ turn.T + [1.0, 2.0, 3.0]
    fit = fit_template(template, moved[np.unique(boundary_facets(template.cells))])
    for name, vectors in (("Fibre", fibre), ("Sheet", sheet), ("SheetNormal", np.cross(fibre, sheet))):
        np.testing.assert_allclose(fit.mesh.cell_data[name], vectors @ turn.T, rtol=0, atol=1e-9)


def test_the_moved_cells_carry_their_own_quality_arrays(sphere_template):
    """Volume and the angles of the cell data are the moved cells', not the template's: the volumes sum to the
    mesh's and scale by 1.2 x 1.0 x 0.8 (the data's stretch) within the fit's 3 %."""
    mesh, _, samples = sphere_template
    template = Mesh(mesh.points, mesh.cells, {"Volume": signed_measures(mesh.points, mesh.cells)})
    fit = fit_template(template, samples * [1.2, 1.0, 0.8])
    np.testing.assert_allclose(fit.mesh.cell_data["Volume"], signed_measures(fit.mesh.points, fit.mesh.cells))
    assert fit.mesh.cell_data["Volume"].sum() == pytest.approx(0.96 * template.cell_data["Volume"].sum(), rel=0.03)


def test_data_of_another_shape_are_refused_naming_the_area_left_bare(sphere_template):
    """Two spheres 6 radii apart as the data of one ball: the fit stretches the ball round both (a similarity of scale
    3) and lies within a mean edge of 95 % of their points, but most of its boundary lies far from every point (a
    fit of the right shape leaves none): refused, saying so, with the hints."""
    mesh, _, samples = sphere_template
    with pytest.raises(MeshingError, match=r"does not take the data's shape: \d+\.\d% of its boundary's area lies "
                                           r"farther than .* from every data point .*another shape.*mapping"):
        fit_template(mesh, np.vstack([samples + [3.0, 0.0, 0.0], samples - [3.0, 0.0, 0.0]]))


def test_a_fit_leaving_its_data_far_is_refused_naming_the_surface_and_the_hints():
    """16 % of the data farther than a mean edge (5 % allowed), all on one surface: the refusal names the
    share, the surface and its count, and the hints with pull's value and range; 4 % passes."""
    distances = np.r_[np.zeros(80), np.full(14, 2.0), np.zeros(4), np.full(2, 2.0)]
    with pytest.raises(MeshingError, match=r"does not follow the data: 16\.0% of the data points lie farther than a "
                                           r"mean edge .*most on RV_ENDO: 16 of its 20\).*fit through the data "
                                           r"between, each from the last.*raise pull \(now 3, allowed \(0, inf\]\)"):
        check_follows(distances, 1.0, 3.0, {"EPI": 80, "RV_ENDO": 20})
    check_follows(np.r_[np.zeros(96), np.full(4, 2.0)], 1.0, 3.0, {"boundary": 100})
