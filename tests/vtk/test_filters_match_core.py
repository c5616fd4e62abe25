"""Each VTK filter gives what the core gives on the same input (the implicit grid, the nodes, the tetrahedra,
the carved domain with or without thin handles, the quality arrays, histogram and summary, the optimised mesh).

Every test here also fails if VTK printed an error or a warning (tests/vtk/conftest.py), unless it asks for the
``vtk_errors`` fixture.
"""
from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest
from bitemesh.algorithms import SpuriousCellFilter
from bitemesh.convert import attach_plan, cell_types, image_to_grid, plan_of, point_coordinates, unstructured_to_mesh
from bitemesh.core.steps.biting import bite
from bitemesh.core.steps.delaunay import delaunay
from bitemesh.core.steps.repair import carve_domain
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import SpuriousParameters
from bitemesh.core.sources.points import points_to_implicit
from bitemesh.core.mesh.quality import cell_quality, quality_histogram, quality_summary
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import VTK_TETRA
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

from tests.builders import field_value, output, polydata
from tests.meshcheck import assert_valid_domain

SPHERE_VOLUME = 4 / 3 * np.pi


# ------------------------------------------------------------------------------------------------ same as the core


def test_points_to_implicit_gives_the_core_grid_and_announces_it(sphere_chain, sphere_samples):
    points, normals = sphere_samples
    image = output(sphere_chain.implicit)
    grid = image_to_grid(image)
    expected = points_to_implicit(points, normals, cells=8000)
    np.testing.assert_array_equal(grid.values, expected.values)
    np.testing.assert_array_equal(grid.origin, expected.origin)
    np.testing.assert_array_equal(grid.spacing, expected.spacing)
    # RequestInformation announced the same grid (downstream image filters rely on it)
    info = sphere_chain.implicit.GetOutputInformation(0)
    assert info.Get(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT()) == image.GetExtent()
    assert info.Get(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT())[1::2] == tuple(n - 1 for n in grid.shape)
    np.testing.assert_allclose(info.Get(image.ORIGIN()), expected.origin)
    np.testing.assert_allclose(info.Get(image.SPACING()), expected.spacing)


def test_biting_sampler_gives_the_core_nodes(sphere_chain):
    grid = image_to_grid(output(sphere_chain.implicit))
    nodes = output(sphere_chain.biting)
    radius = plan_of(nodes)["Radius"]
    assert radius == plan_of(output(sphere_chain.implicit))["Radius"]   # the R the grid was laid out for
    expected = bite(grid, radius, order="boundary", seed=0)
    np.testing.assert_array_equal(point_coordinates(nodes), expected)
    assert nodes.GetNumberOfVerts() == len(expected)  # one vertex cell per node, so that they render


def test_delaunay_tetra_gives_the_core_tetrahedra(sphere_chain):
    nodes = point_coordinates(output(sphere_chain.biting))
    tetrahedra = output(sphere_chain.tetra)
    assert set(cell_types(tetrahedra)) == {VTK_TETRA}
    np.testing.assert_array_equal(point_coordinates(tetrahedra), nodes)
    np.testing.assert_array_equal(unstructured_to_mesh(tetrahedra).cells, delaunay(nodes))


def test_spurious_cell_filter_gives_the_core_domain(sphere_chain):
    grid = image_to_grid(output(sphere_chain.implicit))
    everything = unstructured_to_mesh(output(sphere_chain.tetra))
    domain = unstructured_to_mesh(output(sphere_chain.spurious))
    expected = carve_domain(grid, everything.points, everything.cells, SpuriousParameters())
    np.testing.assert_array_equal(domain.points, expected.points)
    np.testing.assert_array_equal(domain.cells, expected.cells)


@pytest.mark.parametrize("handles, myocardium, euler", [("auto", False, 0), ("auto", True, 2), ("remove", False, 2),
                                                         ("keep", True, 0)])
def test_spurious_cell_filter_removes_thin_handles_when_asked_or_for_a_myocardium(handles, myocardium, euler):
    """A ball with a tunnel thinner than two cells: Handles "auto" fills it when the image says it is a myocardium
    (PointsToImplicit marks a biv-me heart's image so), "remove" always, "keep" never."""
    from bitemesh.convert import grid_to_image, mesh_to_unstructured
    from bitemesh.core.grid.sampled import sample_function
    from tests.meshcheck import assert_valid_domain
    grid = sample_function(lambda x: np.minimum(1.5 - np.linalg.norm(x, axis=1), np.hypot(x[:, 0], x[:, 1]) - 0.2),
                           [-1.7] * 3, [1.7] * 3, 0.25 / 4, margin=0.25)
    image = grid_to_image(grid)
    if myocardium:
        attach_plan(image, Myocardium=1)
    nodes = bite(grid, 0.25)
    spurious = SpuriousCellFilter()
    spurious.SetInputData(0, mesh_to_unstructured(Mesh(nodes, delaunay(nodes))))
    spurious.SetInputData(1, image)
    spurious.SetHandles(handles)
    assert_valid_domain(unstructured_to_mesh(spurious.update()), euler=euler, components=1)


def test_quality_filter_gives_the_core_quality_histogram_and_summary(sphere_chain):
    mesh = unstructured_to_mesh(output(sphere_chain.spurious))
    result = output(sphere_chain.quality)
    expected = cell_quality(mesh)
    assert {result.GetCellData().GetArrayName(i) for i in range(result.GetCellData().GetNumberOfArrays())} == \
        set(expected)
    for name, values in expected.items():
        np.testing.assert_array_equal(vtk_to_numpy(result.GetCellData().GetArray(name)), values, err_msg=name)
    np.testing.assert_array_equal(point_coordinates(result), mesh.points)
    counts, edges = quality_histogram(expected["RadiusRatio"], 20)
    table = output(sphere_chain.quality, 1)
    assert table.GetNumberOfRows() == 20
    np.testing.assert_array_equal(vtk_to_numpy(table.GetColumnByName("Count")), counts)
    np.testing.assert_array_equal(vtk_to_numpy(table.GetColumnByName("BinStart")), edges[:-1])
    np.testing.assert_array_equal(vtk_to_numpy(table.GetColumnByName("BinEnd")), edges[1:])
    assert counts.sum() == result.GetNumberOfCells()
    for name, value in asdict(quality_summary(mesh)).items():
        assert field_value(result, name) == pytest.approx(value, nan_ok=True), name


def test_the_mesh_optimizer_filter_equals_the_core_and_one_shot_optimize_equals_run(small_chain, sphere_samples):
    from bitemesh import MeshFromPoints, MeshOptimizer
    from bitemesh.core.optimize.optimizer import optimize_mesh
    from bitemesh.core.parameters import OptimizeParameters
    pipeline = small_chain
    optimizer = MeshOptimizer()
    optimizer.SetInputConnection(0, pipeline.filters[3].GetOutputPort())
    optimizer.SetInputConnection(1, pipeline.filters[0].GetOutputPort())
    optimized = unstructured_to_mesh(optimizer.update())
    carved = unstructured_to_mesh(pipeline.filters[3].GetOutputDataObject(0))
    grid = image_to_grid(pipeline.filters[0].GetOutputDataObject(0))
    expected = optimize_mesh(grid, Mesh(carved.points, carved.cells), OptimizeParameters())
    assert np.array_equal(optimized.points, expected.points) and np.array_equal(optimized.cells, expected.cells)
    assert_valid_domain(optimized, euler=2, components=1, mean_quality=0.85)
    points, normals = sphere_samples
    one_shot = MeshFromPoints()
    one_shot.SetInputData(polydata(points, normals))
    one_shot.SetCells(1000)
    one_shot.SetOptimize(1)
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters
    from bitemesh.core.sources.points import run
    result = run(points, normals, ImplicitParameters(), BitingParameters(cells=1000), SpuriousParameters(),
                 optimize=OptimizeParameters(optimize=1))
    assert np.array_equal(unstructured_to_mesh(one_shot.update()).cells, result.mesh.cells)
