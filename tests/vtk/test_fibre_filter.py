"""FibreField (bitemesh.algorithms.fibres): the tagged two-cavity shell as a vtkUnstructuredGrid and its tagged
facets as a vtkPolyData on the same points (bitemesh.convert.tags_to_polydata) give what the core gives, bit for
bit, and a wrong port 1 is refused saying why."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from bitemesh import FibreField
from bitemesh.convert import mesh_to_unstructured, tags_to_polydata, vtk_points
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.fibres import FIBRE_ARRAYS, LAPLACE_ARRAYS, FibreParameters, fibre_field
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkPolyData

from tests.fibrecheck import tagged_shell


def tagged_polydata(mesh, names=None) -> vtkPolyData:
    """The mesh's tagged facets as the meshing filters' second output, with other names if given."""
    return tags_to_polydata(mesh if names is None else replace(mesh, tag_names=names))


@pytest.fixture(scope="module")
def shell():
    mesh = tagged_shell()
    return mesh, mesh_to_unstructured(mesh), tagged_polydata(mesh)


def run_filter(grid, facets, **angles):
    algorithm = FibreField()
    algorithm.SetInputData(0, grid)
    algorithm.SetInputData(1, facets)
    for name, value in angles.items():
        getattr(algorithm, f"Set{''.join(part.capitalize() for part in name.split('_'))}")(value)
    return algorithm.update()


def test_the_filter_adds_the_cores_fibres_and_keeps_the_input(shell):
    mesh, grid, facets = shell
    before = {name: vtk_to_numpy(grid.GetCellData().GetArray(name)).copy() for name in mesh.cell_data}
    output = run_filter(grid, facets)
    expected = fibre_field(mesh)
    for name, values in zip(FIBRE_ARRAYS, (expected.fibre, expected.sheet, expected.sheet_normal,
                                           expected.helix_angle)):
        assert np.array_equal(vtk_to_numpy(output.GetCellData().GetArray(name)), values), name
    for name in LAPLACE_ARRAYS:
        assert np.array_equal(vtk_to_numpy(output.GetPointData().GetArray(name)), expected.laplace[name]), name
    assert output.GetCellData().GetVectors().GetName() == "Fibre"
    for name, values in before.items():   # the input's arrays pass on, and the input is as it was
        assert np.array_equal(vtk_to_numpy(output.GetCellData().GetArray(name)), values)
        assert np.array_equal(vtk_to_numpy(grid.GetCellData().GetArray(name)), values)
    assert grid.GetCellData().GetArray("Fibre") is None and grid.GetPointData().GetNumberOfArrays() == 0


def test_the_angles_reach_the_core(shell):
    mesh, grid, facets = shell
    angles = dict(alpha_endo=60.0, alpha_epi=-60.0, beta_endo=0.0, beta_epi=0.0)
    output = run_filter(grid, facets, **angles)
    expected = fibre_field(mesh, FibreParameters(**angles))
    assert np.array_equal(vtk_to_numpy(output.GetCellData().GetArray("Fibre")), expected.fibre)


def test_facets_without_the_heart_surfaces_are_refused_naming_them(shell, vtk_errors):
    mesh, grid, facets = shell
    names = {name: value for name, value in mesh.tag_names.items() if name != "RV_ENDO"}
    with pytest.raises(InvalidInputError, match=r"has no RV_ENDO \(its facet tags: BASE, EPI, LV_ENDO\)"):
        run_filter(grid, tagged_polydata(mesh, names))
    assert "FibreField: fibres need the boundary surfaces" in vtk_errors.text()


@pytest.mark.parametrize("wrong, message", [
    ("no names", r"has no EPI, LV_ENDO, RV_ENDO, BASE \(its facet tags: none\)"),
    ("other points", r"the tagged facets' points are not the mesh's.*connect the tagged facets of this mesh"),
    ("fewer points", r"the tagged facets hold 3 points and the mesh \d+.*connect the tagged facets of this mesh"),
])
def test_a_port_1_that_is_not_this_meshs_tagged_facets_is_refused_saying_why(shell, wrong, message, vtk_errors):
    mesh, grid, facets = shell
    other = vtkPolyData()
    other.DeepCopy(facets)
    if wrong == "no names":
        other.GetFieldData().Initialize()
    elif wrong == "other points":
        other.SetPoints(vtk_points(mesh.points + 1.0))
    else:
        other = tagged_polydata(type(mesh)(mesh.points[:3], mesh.cells[:0], {}, mesh.facets[:0], mesh.facet_tags[:0]))
    with pytest.raises(InvalidInputError, match=message):
        run_filter(grid, other)
