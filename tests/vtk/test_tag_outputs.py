"""The tags on the VTK side: MeshFromPoints' second output (the tagged facets as a vtkPolyData sharing the mesh's
points, ``SurfaceTag``, the names as field data), the ``Region`` cell array, and the converters both ways."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import MeshFromPoints
from bitemesh.convert import (REGION_ARRAY, SURFACE_TAG_ARRAY, TAG_NAME_ARRAYS, point_coordinates, tag_names_of,
                              tags_to_polydata, unstructured_to_mesh, with_polydata_tags)
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.sources.points import run
from bitemesh.core.mesh.tags import component_tags, region_tags
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import VTK_LINE, VTK_TRIANGLE

from tests.builders import cube_mesh, polydata, sphere_samples, square_mesh
from tests.meshcheck import assert_tagged


def two_spheres():
    points, normals = sphere_samples(0.1)
    return np.vstack([points, 0.5 * points + [3.0, 0, 0]]), np.vstack([normals, normals])


def test_mesh_from_points_gives_the_cores_tags_on_its_second_port():
    points, normals = two_spheres()
    algorithm = MeshFromPoints()
    algorithm.SetInputData(polydata(points, normals))
    algorithm.SetCells(3000)
    algorithm.SetOptimize(0)
    grid, facets = algorithm.update(0), algorithm.GetOutputDataObject(1)
    expected = run(points, normals, biting=BitingParameters(cells=3000), optimize=OptimizeParameters(optimize=0)).mesh
    mesh = with_polydata_tags(unstructured_to_mesh(grid), facets)
    assert_tagged(mesh)
    np.testing.assert_array_equal(mesh.facets, expected.facets)
    np.testing.assert_array_equal(mesh.facet_tags, expected.facet_tags)
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray(REGION_ARRAY)), np.ones(len(mesh.cells)))
    # the facets share every point of the mesh, are triangles, and name every tag
    np.testing.assert_array_equal(point_coordinates(facets), point_coordinates(grid))
    assert {facets.GetCellType(i) for i in range(facets.GetNumberOfCells())} == {VTK_TRIANGLE}
    assert tag_names_of(facets) == tag_names_of(grid) == {"BOUNDARY_1": (1, 2), "BOUNDARY_2": (2, 2),
                                                          "DOMAIN": (1, 3)}
    names = facets.GetFieldData().GetAbstractArray(TAG_NAME_ARRAYS[0])
    assert names.IsA("vtkStringArray") and all(facets.GetFieldData().GetArray(name).IsA("vtkIntArray")
                                               for name in TAG_NAME_ARRAYS[1:])
    assert facets.GetCellData().GetArray(SURFACE_TAG_ARRAY).GetDataType() == grid.GetCellData().GetArray(
        REGION_ARRAY).GetDataType() == 6   # VTK_INT: int32


def test_a_failed_run_leaves_both_ports_empty(vtk_errors):
    algorithm = MeshFromPoints()
    algorithm.SetInputData(polydata(*sphere_samples(0.2)))
    algorithm.SetRadius(-2.0)
    with pytest.raises(InvalidInputError):
        algorithm.update()
    assert [algorithm.GetOutputDataObject(port).GetNumberOfPoints() for port in (0, 1)] == [0, 0]
    assert "MeshFromPoints: radius must be in" in vtk_errors.text()


@pytest.mark.parametrize("make", [lambda: region_tags(cube_mesh(), cube_mesh().cell_data["Label"], [1, 2]),
                                  lambda: component_tags(square_mesh())], ids=["regions-3d", "boundary-2d"])
def test_the_tags_go_to_vtk_and_back_unchanged(make):
    mesh = make()
    facets = tags_to_polydata(mesh)
    kind = VTK_TRIANGLE if mesh.dim == 3 else VTK_LINE
    assert {facets.GetCellType(i) for i in range(facets.GetNumberOfCells())} == {kind}
    back = with_polydata_tags(type(mesh)(mesh.points, mesh.cells, mesh.cell_data), facets)
    np.testing.assert_array_equal(back.facets, mesh.facets)
    np.testing.assert_array_equal(back.facet_tags, mesh.facet_tags)
    assert back.facet_tags.dtype == np.int32 and back.tag_names == mesh.tag_names


def test_tags_of_another_mesh_or_without_their_array_are_refused():
    mesh = region_tags(cube_mesh(), cube_mesh().cell_data["Label"], [1, 2])
    other = component_tags(square_mesh())
    with pytest.raises(InvalidInputError, match=r"the tagged facets hold 4 points and the mesh 8: they must share "
                                                r"the mesh's points .*second output, port 1"):
        with_polydata_tags(mesh, tags_to_polydata(other))
    moved = tags_to_polydata(type(mesh)(mesh.points + 1.0, mesh.cells, {}, mesh.facets, mesh.facet_tags,
                                        mesh.tag_names))
    with pytest.raises(InvalidInputError, match="points are not the mesh's"):
        with_polydata_tags(mesh, moved)
    facets = tags_to_polydata(mesh)
    facets.GetCellData().RemoveArray(SURFACE_TAG_ARRAY)
    with pytest.raises(InvalidInputError, match=f"no cell array {SURFACE_TAG_ARRAY}"):
        with_polydata_tags(mesh, facets)
    facets = tags_to_polydata(mesh)
    facets.GetFieldData().RemoveArray(TAG_NAME_ARRAYS[2])
    with pytest.raises(InvalidInputError, match="TagNames, TagValues, TagDimensions must be"):
        with_polydata_tags(mesh, facets)
