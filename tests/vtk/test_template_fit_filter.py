"""TemplateFit (bitemesh.algorithms.fit): the tagged two-cavity shell and its tagged facets, fitted to its own
boundary turned and scaled, given as a vtkPolyData of points: the VTK output is the core's fit, bit for bit, with
the same cells and tags; the chain goes on (port 1 feeds the next frame's fit)."""
from __future__ import annotations

import numpy as np
from bitemesh import TemplateFit
from bitemesh.convert import mesh_to_unstructured, point_coordinates, tags_to_polydata, unstructured_to_mesh, \
    vtk_points
from bitemesh.core.fem.template import fit_template
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
    algorithm.Update()
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
