"""TemplateFit (bitemesh.algorithms.fit): the tagged two-cavity shell and its tagged facets, fitted to its own
boundary turned and scaled, given as a vtkPolyData of points: the VTK output is the core's fit, bit for bit, with
the same cells and tags; the chain goes on (port 1 feeds the next frame's fit)."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import InvalidInputError, TemplateFit
from bitemesh.convert import mesh_to_unstructured, point_coordinates, tags_to_polydata, unstructured_to_mesh, \
    vtk_points
from bitemesh.core.fem.template import fit_template
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.mesh.topology import boundary_facets
from vtkmodules.vtkCommonDataModel import vtkPolyData

from tests.fibrecheck import tagged_shell

TURN = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def points_polydata(points: np.ndarray) -> vtkPolyData:
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points(points))
    return polydata


def fitted(grid, facets, data, pull=None):
    algorithm = TemplateFit()
    for port, item in enumerate((grid, facets, data)):
        algorithm.SetInputData(port, item)
    if pull is not None:
        algorithm.SetPull(pull)
    algorithm.update()
    return algorithm


def test_the_filter_gives_the_cores_fit_and_chains_on():
    mesh = tagged_shell()
    data = 1.5 * mesh.points[np.unique(boundary_facets(mesh.cells))] @ TURN.T
    algorithm = fitted(mesh_to_unstructured(mesh), tags_to_polydata(mesh), points_polydata(data))
    output = unstructured_to_mesh(algorithm.GetOutputDataObject(0))
    expected = fit_template(mesh, data)
    np.testing.assert_array_equal(output.points, expected.mesh.points)
    np.testing.assert_array_equal(output.cells, mesh.cells)
    np.testing.assert_allclose(output.points, 1.5 * mesh.points @ TURN.T, rtol=0, atol=1e-9)
    surfaces = algorithm.GetOutputDataObject(1)
    np.testing.assert_array_equal(point_coordinates(surfaces), output.points)
    again = fitted(algorithm.GetOutputDataObject(0), surfaces, points_polydata(data), pull=1.0)
    np.testing.assert_allclose(point_coordinates(again.GetOutputDataObject(0)), output.points, rtol=0, atol=1e-9)


@pytest.mark.parametrize("change, message", [
    ({"pull": -1.0}, r"pull must be in \(0, inf\], got -1.0"),
    ({"data": np.arange(1.0, 10.0).reshape(3, 3)}, "data: at least 4 points are needed, got 3"),
    ({"facets": "other mesh"}, "the tagged facets hold"),
])
def test_bad_input_is_refused_naming_it_and_the_pipeline_goes_on(change, message, vtk_errors):
    """A bad Pull, too few data points, port 1 of another mesh: update() raises the core's message (the parameter,
    the value, the range), VTK prints it once, and the filter runs again once the input is mended."""
    mesh = tagged_shell()
    grid, facets = mesh_to_unstructured(mesh), tags_to_polydata(mesh)
    data = mesh.points[np.unique(boundary_facets(mesh.cells))]
    bad_facets = tags_to_polydata(Mesh(mesh.points[:-1], mesh.cells[:0])) if "facets" in change else facets
    with pytest.raises(InvalidInputError, match=message):
        fitted(grid, bad_facets, points_polydata(change.get("data", data)), pull=change.get("pull"))
    assert "TemplateFit" in vtk_errors.text()
    vtk_errors.clear()
    assert fitted(grid, facets, points_polydata(data)).GetOutputDataObject(0).GetNumberOfCells() == len(mesh.cells)
