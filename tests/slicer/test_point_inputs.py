"""BiteMeshLogic on points: a markups point list (the same mesh as bitemesh.run, with and without the optimizer;
the histogram table and plot nodes), closed curves, and a model's points and normals through its transform.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

from bitemesh.core.sources.points import run as points_run
import numpy as np
import pytest
from bitemesh.core.parameters import BitingParameters, ImplicitParameters, QualityParameters, SpuriousParameters

from tests.builders import vtk_sphere
from tests.meshcheck import assert_valid_domain, centroid
from tests.slicer.scenes import (CENTRE, RADIUS, closed_curves, mesh_of, output_model, point_list, sphere_points,
                                 translation)
from BiteMeshLib import outputs as lib_outputs  # on sys.path from tests.slicer.scenes
from BiteMeshLib import points as lib_points


# --- markups point list ---------------------------------------------------------------------------------------------

def test_point_list_gives_valid_tetrahedra_at_the_sphere(scene, logic):
    model = output_model(scene)
    result = logic.process(point_list(scene, sphere_points()), model, cells=3000)
    mesh = mesh_of(model)
    volume = 4 / 3 * np.pi * RADIUS**3
    assert_valid_domain(mesh, euler=2, components=1, measure=volume, measure_tolerance=0.05, mean_quality=0.6)
    assert np.linalg.norm(centroid(mesh) - CENTRE) < 0.5
    assert 2000 < len(mesh.cells) < 4500
    assert result.mesh.cells.shape == mesh.cells.shape
    display = model.GetDisplayNode()
    assert display is not None and display.GetActiveScalarName() == "RadiusRatio"
    assert display.GetScalarVisibility()
    assert model.GetMesh().GetCellData().GetArray("RadiusRatio") is not None
    assert model.GetMesh().GetFieldData().GetArray("Radius").GetValue(0) == pytest.approx(result.radius)


def test_point_list_mesh_equals_bitemesh_run(scene, logic):
    """Same points (RAS), same parameters: the same mesh as bitemesh.run, point for point and cell for cell."""
    points = sphere_points(800, seed=7)
    model = output_model(scene)
    parameters = {"radius": 4.0, "grid_spacing": 1.0, "threshold": 0.4, "seed": 3}
    logic.process(point_list(scene, points), model, **parameters)
    expected = points_run(points, None, ImplicitParameters(grid_spacing=1.0), BitingParameters(radius=4.0, seed=3),
                            SpuriousParameters(threshold=0.4)).mesh
    mesh = mesh_of(model)
    assert mesh.points.shape == expected.points.shape and mesh.cells.shape == expected.cells.shape
    np.testing.assert_array_equal(mesh.cells, expected.cells)
    np.testing.assert_array_equal(mesh.points, expected.points)
    np.testing.assert_array_equal(mesh.cell_data["RadiusRatio"], expected.cell_data["RadiusRatio"])


def test_histogram_table_and_plot_nodes(scene, logic):
    model = output_model(scene, "sphere mesh")
    result = logic.process(point_list(scene, sphere_points(600)), model, radius=5.0, bins=10)
    table = result.tableNode
    assert table.IsA("vtkMRMLTableNode") and table.GetScene() is scene
    assert table.GetNumberOfRows() == 10
    columns = [table.GetColumnName(i) for i in range(table.GetNumberOfColumns())]
    assert columns == ["BinStart", "BinEnd", "BinCentre", "Count"]
    counts = [table.GetTable().GetValueByName(row, "Count").ToInt() for row in range(10)]
    assert sum(counts) == len(mesh_of(model).cells)
    series, chart = result.seriesNode, result.chartNode
    assert series.IsA("vtkMRMLPlotSeriesNode") and chart.IsA("vtkMRMLPlotChartNode")
    assert series.GetTableNodeID() == table.GetID()
    assert (series.GetXColumnName(), series.GetYColumnName()) == ("BinCentre", "Count")
    assert series.GetPlotType() == series.PlotTypeBar
    assert chart.GetNumberOfPlotSeriesNodes() == 1 and chart.GetNthPlotSeriesNodeID(0) == series.GetID()
    assert model.GetNodeReference(lib_outputs.TABLE_ROLE) is table

    # A second run reuses the same nodes instead of piling new ones into the scene.
    tables = scene.GetNumberOfNodesByClass("vtkMRMLTableNode")
    again = logic.process(point_list(scene, sphere_points(600, seed=2)), model, radius=5.0)
    assert again.tableNode is table and again.chartNode is chart and again.seriesNode is series
    assert scene.GetNumberOfNodesByClass("vtkMRMLTableNode") == tables
    assert chart.GetNumberOfPlotSeriesNodes() == 1
    assert table.GetNumberOfRows() == QualityParameters().bins


def test_optimize_runs_the_mesh_optimizer_like_bitemesh_run(scene, logic):
    """optimize=1 on a point list (RAS in, RAS out: no transform): the optimised mesh of bitemesh.run with the same
    parameters, point for point and cell for cell, with its quality arrays."""
    from bitemesh.core.parameters import OptimizeParameters
    from bitemesh.core.sources.points import run
    points = sphere_points()
    model = output_model(scene)
    result = logic.process(point_list(scene, points), model, cells=2000, optimize=1)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, mean_quality=0.85)
    expected = run(points, None, ImplicitParameters(), BitingParameters(cells=2000), SpuriousParameters(),
                   optimize=OptimizeParameters(optimize=1)).mesh
    assert mesh.points.shape == expected.points.shape and mesh.cells.shape == expected.cells.shape
    np.testing.assert_array_equal(mesh.cells, expected.cells)
    np.testing.assert_array_equal(mesh.points, expected.points)
    np.testing.assert_array_equal(mesh.cell_data["RadiusRatio"], expected.cell_data["RadiusRatio"])
    assert result.summary.q_mean >= 0.85


# --- closed curves and models ---------------------------------------------------------------------------------------

def test_closed_curves_give_a_valid_mesh(scene, logic):
    model = output_model(scene)
    result = logic.process(closed_curves(scene), model, radius=4.0, method="rbf")
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1)
    assert np.linalg.norm(centroid(mesh)[:2] - CENTRE[:2]) < 0.5
    low, high = mesh.points[:, 2].min(), mesh.points[:, 2].max()
    assert low < CENTRE[2] - 0.7 * RADIUS and high > CENTRE[2] + 0.7 * RADIUS   # spans the contours
    assert len(result.mesh.cells) > 500


def test_closed_curves_default_to_rbf(scene, logic):
    """Sparse contours take the RBF unless a method is given; the contour normals point outward."""
    nodes = closed_curves(scene, levels=(-0.5, 0.0, 0.5))
    points, normals, slices = lib_points.scatteredPoints(nodes, "rbf")
    assert len(np.unique(slices)) == len(nodes)   # one slice per curve
    assert normals is not None and len(points) <= lib_points.RBF_CURVE_POINTS
    outward = np.einsum("ij,ij->i", normals, points - CENTRE)
    assert (outward > 0).all()
    assert np.allclose(normals[:, 2], 0.0, atol=1e-9)   # in the contours' planes


def test_model_points_and_normals_through_its_transform(scene, logic):
    surface = scene.AddNewNodeByClass("vtkMRMLModelNode", "surface")
    surface.SetAndObservePolyData(vtk_sphere(RADIUS, (48, 36)))
    surface.SetAndObserveTransformNodeID(translation(scene, CENTRE).GetID())
    model = output_model(scene)
    logic.process(surface, model, cells=2000)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * RADIUS**3, measure_tolerance=0.05)
    assert np.linalg.norm(centroid(mesh) - CENTRE) < 0.5
