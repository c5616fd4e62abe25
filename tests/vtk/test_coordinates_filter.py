"""VentricularCoordinates (bitemesh.algorithms.coordinates): the tagged two-cavity shell and its tagged facets in,
the core's coordinates out, bit for bit, every input array kept; a mesh without the heart's surfaces is refused
naming them, and the filter runs again once given good input."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import InvalidInputError, VentricularCoordinates
from bitemesh.convert import mesh_to_unstructured, tags_to_polydata
from bitemesh.core.fem.coordinates import ventricular_coordinates
from vtkmodules.util import numpy_support

from tests.builders import cube_mesh
from tests.fibrecheck import tagged_shell


def run(mesh):
    algorithm = VentricularCoordinates()
    algorithm.SetInputData(0, mesh_to_unstructured(mesh))
    algorithm.SetInputData(1, tags_to_polydata(mesh))
    algorithm.update()
    return algorithm


def test_the_filter_gives_the_cores_coordinates():
    mesh = tagged_shell()
    output = run(mesh).GetOutputDataObject(0)
    expected = ventricular_coordinates(mesh)
    for name, values in expected.points.items():
        np.testing.assert_array_equal(numpy_support.vtk_to_numpy(output.GetPointData().GetArray(name)), values)
    for name, values in (("AHA", expected.aha), ("Ventricle", expected.ventricle)):
        np.testing.assert_array_equal(numpy_support.vtk_to_numpy(output.GetCellData().GetArray(name)), values)
    assert output.GetCellData().GetArray("RadiusRatio") is not None   # the input's arrays stay
    assert output.GetCellData().GetScalars().GetName() == "AHA"


def test_a_mesh_without_the_heart_surfaces_is_refused_then_the_filter_runs_again(vtk_errors):
    with pytest.raises(InvalidInputError, match=r"has no EPI, LV_ENDO, RV_ENDO, BASE"):
        run(cube_mesh())
    assert "VentricularCoordinates" in vtk_errors.text()
    vtk_errors.clear()
    assert run(tagged_shell()).GetOutputDataObject(0).GetNumberOfCells() == len(tagged_shell().cells)
