"""BiteMeshLogic against the real MRML classes of the PyPI package slicer-core (its own virtual environment).

Run: cd /work/main && PYTHONPATH=filters /work/slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
import pytest

slicer = pytest.importorskip("slicer")
if not hasattr(slicer, "vtkMRMLScene"):   # PyPI also has an unrelated package named "slicer"
    pytest.skip("the 'slicer' module found is not slicer-core (no vtkMRMLScene)", allow_module_level=True)

import ast  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from dataclasses import fields  # noqa: E402
from pathlib import Path  # noqa: E402
from xml.etree import ElementTree  # noqa: E402

import bitemesh  # noqa: E402
import numpy as np  # noqa: E402
from bitemesh import Cancelled, InvalidInputError  # noqa: E402
from bitemesh.convert import (  # noqa: E402
    cell_types,
    nodes_to_polydata,
    point_coordinates,
    unstructured_to_mesh,
)
from bitemesh.core.labelled import run_labelled  # noqa: E402
from bitemesh.core.parameters import (  # noqa: E402
    BitingParameters,
    ImplicitParameters,
    LabelledParameters,
    QualityParameters,
    SpuriousParameters,
)
from bitemesh.io import read_labelled_points  # noqa: E402
from vtkmodules.util import numpy_support  # noqa: E402
from vtkmodules.vtkCommonCore import VTK_SHORT  # noqa: E402
from vtkmodules.vtkCommonDataModel import VTK_TETRA, vtkImageData  # noqa: E402
from vtkmodules.vtkCommonMath import vtkMatrix4x4  # noqa: E402
from vtkmodules.vtkFiltersSources import vtkSphereSource  # noqa: E402

from tests.core.test_labelled import SHELL_DOMAIN, sample_shell  # noqa: E402
from tests.meshcheck import assert_valid_domain  # noqa: E402
from tests.vtk.test_labelled_filters import SHELL_VOLUME, labelled_polydata  # noqa: E402

MODULE = Path(__file__).resolve().parents[2] / "slicer_module" / "BiteMesh"
sys.path.insert(0, str(MODULE))
from BiteMeshLib import logic as bitemesh_logic  # noqa: E402
from BiteMeshLib import contours as lib_contours  # noqa: E402
from BiteMeshLib import outputs as lib_outputs  # noqa: E402
from BiteMeshLib import parameters as lib_parameters  # noqa: E402
from BiteMeshLib import points as lib_points  # noqa: E402
from BiteMeshLib import requirements as lib_requirements  # noqa: E402
from BiteMeshLib import selftest  # noqa: E402
from BiteMeshLib.logic import BiteMeshLogic  # noqa: E402

CENTRE = np.array([30.0, -40.0, 55.0])   # RAS, mm: off the origin, so that a wrong frame shows
GPFILE = Path(bitemesh.__file__).resolve().parent / "data" / "bivme_patient1" / "GPFile_000.txt"
RADIUS = 20.0
BALL_RADIUS = 12.0


@pytest.fixture(autouse=True)
def no_vtk_errors(capfd):
    """Fail a test in which VTK or MRML printed an error or a warning (they do not raise)."""
    yield
    captured = capfd.readouterr()
    printed = [line for line in (captured.out + captured.err).splitlines()
               if any(mark in line for mark in (" ERR| ", " WARN| ", "ERROR:", "Warning:"))]
    assert not printed, "VTK printed:\n" + "\n".join(printed)


@pytest.fixture
def scene():
    return slicer.vtkMRMLScene()


@pytest.fixture
def logic():
    return BiteMeshLogic()


def sphere_points(count=1500, seed=1):
    directions = np.random.default_rng(seed).normal(size=(count, 3))
    return CENTRE + RADIUS * directions / np.linalg.norm(directions, axis=1, keepdims=True)


def point_list(scene, points, name="points"):
    node = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", name)
    for point in points:
        node.AddControlPoint(*map(float, point))
    return node


def output_model(scene, name="mesh"):
    return scene.AddNewNodeByClass("vtkMRMLModelNode", name)


def mesh_of(model):
    grid = model.GetMesh()
    assert grid is not None and grid.IsA("vtkUnstructuredGrid")
    assert set(cell_types(grid).tolist()) == {VTK_TETRA}
    return unstructured_to_mesh(grid)


def centroid(mesh):
    corners = mesh.points[mesh.cells]
    volumes = np.linalg.det(corners[:, 1:] - corners[:, :1]) / 6.0
    return (corners.mean(axis=1) * volumes[:, None]).sum(axis=0) / volumes.sum()


def translation(scene, shift) -> object:
    """A linear transform node that moves its children by ``shift`` (3,) mm."""
    transform = scene.AddNewNodeByClass("vtkMRMLLinearTransformNode")
    matrix = vtkMatrix4x4()
    for axis in range(3):
        matrix.SetElement(axis, 3, float(shift[axis]))
    transform.SetMatrixTransformToParent(matrix)
    return transform


def ball_segmentation(scene, direction, spacing=(0.8, 0.6, 1.2), origin=(10.0, -20.0, 5.0), dims=(40, 50, 28)):
    """A ball segment imported from a label map with the given geometry; returns it and the ball's RAS centre."""
    spacing = np.asarray(spacing)
    labelmap = scene.AddNewNodeByClass("vtkMRMLLabelMapVolumeNode", "ball")
    labelmap.SetSpacing(*spacing)
    labelmap.SetOrigin(*origin)
    matrix = vtkMatrix4x4()
    for row in range(3):
        for column in range(3):
            matrix.SetElement(row, column, float(direction[row, column]))
    labelmap.SetIJKToRASDirectionMatrix(matrix)
    centre_ijk = np.array([18.0, 27.0, 13.0])
    index = np.stack(np.meshgrid(*[np.arange(n) for n in dims], indexing="ij"), axis=-1)
    inside = np.linalg.norm((index - centre_ijk) * spacing, axis=-1) < BALL_RADIUS
    image = vtkImageData()
    image.SetDimensions(*dims)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk((inside * 5).astype(np.uint8).ravel(order="F"),
                                                               deep=True))
    labelmap.SetAndObserveImageData(image)
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode", "segmentation")
    assert slicer.vtkSlicerSegmentationsModuleLogic.ImportLabelmapToSegmentationNode(labelmap, segmentation)
    ijk_to_ras = vtkMatrix4x4()
    labelmap.GetIJKToRASMatrix(ijk_to_ras)
    centre = np.array(ijk_to_ras.MultiplyPoint([*centre_ijk, 1.0])[:3])
    voxel_volume = inside.sum() * np.prod(spacing)
    return segmentation, centre, voxel_volume


def rotation_z(degrees):
    angle = np.radians(degrees)
    return np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])


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
    expected = bitemesh.run(points, None, ImplicitParameters(grid_spacing=1.0), BitingParameters(radius=4.0, seed=3),
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


# --- segmentation ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("direction", [
    pytest.param(np.diag([-1.0, -1.0, 1.0]) @ rotation_z(30), id="rotated"),
    pytest.param(np.diag([-1.0, 1.0, 1.0]), id="reflected"),
])
def test_segmentation_gives_tetrahedra_where_the_segment_is(scene, logic, direction):
    segmentation, centre, voxel_volume = ball_segmentation(scene, direction)
    model = output_model(scene)
    logic.process(segmentation, model, cells=3000)
    mesh = mesh_of(model)
    volume = 4 / 3 * np.pi * BALL_RADIUS**3
    assert voxel_volume == pytest.approx(volume, rel=0.03)   # the label map itself is a fair ball
    assert_valid_domain(mesh, euler=2, components=1, measure=volume, measure_tolerance=0.05, mean_quality=0.5)
    assert np.linalg.norm(centroid(mesh) - centre) < 0.5
    radii = np.linalg.norm(mesh.points - centre, axis=1)
    assert radii.max() < BALL_RADIUS + 1.0


def test_optimize_relaxes_a_segment_in_place(scene, logic):
    segmentation, centre, _ = ball_segmentation(scene, np.diag([-1.0, 1.0, 1.0]))
    model = output_model(scene)
    result = logic.process(segmentation, model, cells=3000, optimize=1)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * BALL_RADIUS**3, measure_tolerance=0.05,
                        mean_quality=0.85)
    assert result.summary.angle_min >= 20.0
    assert np.linalg.norm(centroid(mesh) - centre) < 0.5


def test_segmentation_follows_its_parent_transform(scene, logic):
    segmentation, centre, _ = ball_segmentation(scene, np.eye(3))
    shift = np.array([5.0, -7.0, 11.0])
    segmentation.SetAndObserveTransformNodeID(translation(scene, shift).GetID())
    model = output_model(scene)
    logic.process(segmentation, model, radius=3.0)
    assert np.linalg.norm(centroid(mesh_of(model)) - (centre + shift)) < 0.5


def test_closed_surface_segment_is_converted(scene, logic):
    """A segment whose source is a closed surface (imported from a model) is meshed through its labelmap."""
    factory = slicer.vtkSegmentationConverterFactory.GetInstance()
    if not factory.GetConverterRules():   # Slicer registers the rules at startup; slicer-core does not
        factory.RegisterConverterRule(slicer.vtkBinaryLabelmapToClosedSurfaceConversionRule())
        factory.RegisterConverterRule(slicer.vtkClosedSurfaceToBinaryLabelmapConversionRule())
    source = vtkSphereSource()
    source.SetCenter(*CENTRE)
    source.SetRadius(BALL_RADIUS)
    source.SetThetaResolution(64)
    source.SetPhiResolution(64)
    source.Update()
    reference = scene.AddNewNodeByClass("vtkMRMLScalarVolumeNode", "reference")   # the image it was drawn on
    image = vtkImageData()
    image.SetDimensions(40, 40, 40)
    image.AllocateScalars(VTK_SHORT, 1)
    reference.SetAndObserveImageData(image)
    reference.SetSpacing(0.8, 0.8, 0.8)
    reference.SetOrigin(*(CENTRE - 16.0))
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode")
    segmentation.SetReferenceImageGeometryParameterFromVolumeNode(reference)
    segmentation.GetSegmentation().SetSourceRepresentationName("Closed surface")
    segmentation.AddSegmentFromClosedSurfaceRepresentation(source.GetOutput(), "ball", [1.0, 0.0, 0.0])
    model = output_model(scene)
    logic.process(segmentation, model, cells=3000)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * BALL_RADIUS**3, measure_tolerance=0.05)
    assert np.linalg.norm(centroid(mesh) - CENTRE) < 0.5


def test_segment_is_chosen_by_id(scene, logic):
    segmentation, _, _ = ball_segmentation(scene, np.eye(3))
    with pytest.raises(InvalidInputError, match="not a segment"):
        logic.process(segmentation, output_model(scene), segmentId="nope")
    first = segmentation.GetSegmentation().GetNthSegmentID(0)
    result = logic.process(segmentation, output_model(scene), segmentId=first, radius=3.0)
    assert len(result.mesh.cells) > 100


# --- closed curves and models ---------------------------------------------------------------------------------------

def closed_curves(scene, levels=(-0.75, -0.4, 0.0, 0.4, 0.75), control_points=12):
    nodes = []
    for index, level in enumerate(levels):
        ring = RADIUS * np.sqrt(1 - level**2)
        node = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", f"contour {index}")
        for angle in np.linspace(0, 2 * np.pi, control_points, endpoint=False):
            node.AddControlPoint(CENTRE[0] + ring * np.cos(angle), CENTRE[1] + ring * np.sin(angle),
                                 CENTRE[2] + RADIUS * level)
        nodes.append(node)
    return nodes


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
    source = vtkSphereSource()
    source.SetRadius(RADIUS)
    source.SetThetaResolution(48)
    source.SetPhiResolution(36)
    source.Update()
    surface = scene.AddNewNodeByClass("vtkMRMLModelNode", "surface")
    surface.SetAndObservePolyData(source.GetOutput())
    surface.SetAndObserveTransformNodeID(translation(scene, CENTRE).GetID())
    model = output_model(scene)
    logic.process(surface, model, cells=2000)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * RADIUS**3, measure_tolerance=0.05)
    assert np.linalg.norm(centroid(mesh) - CENTRE) < 0.5


# --- labelled contours ----------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_a_loaded_gpfile_meshes_as_run_labelled(scene, logic):
    """biv-me's guide points, loaded as a model (LPS file -> RAS), give run_labelled's mesh of the same points."""
    node = logic.loadLabelledPoints(GPFILE, scene=scene)
    points, labels, slices = read_labelled_points(GPFILE)
    data = node.GetPolyData()
    assert node.GetName() == "GPFile_000" and data.GetNumberOfVerts() == len(points)
    ras = points * [-1.0, -1.0, 1.0]
    np.testing.assert_array_equal(point_coordinates(data), ras)
    assert data.GetPointData().GetAbstractArray("Label").IsA("vtkStringArray")
    model_labels, model_slices = lib_contours.modelLabels(node)
    assert model_labels.tolist() == labels.tolist() and model_slices.tolist() == slices.tolist()
    as_ras = logic.loadLabelledPoints(GPFILE, "as RAS", scene=scene, coordinateSystem="RAS")
    np.testing.assert_array_equal(point_coordinates(as_ras.GetPolyData()), points)

    model = output_model(scene)
    result = logic.process(node, model, cells=15000)
    expected = run_labelled(ras, labels, slices=slices, biting=BitingParameters(cells=15000)).mesh
    mesh = mesh_of(model)
    np.testing.assert_array_equal(mesh.cells, expected.cells)
    np.testing.assert_array_equal(mesh.points, expected.points)
    assert_valid_domain(mesh, components=1)
    assert result.radius > 0 and 12000 < len(mesh.cells) < 18000


def shell_curves(scene):
    """The closed two-cavity shell's contours as closed curves, one per slice and surface, named as a user would:
    EPI, EPI_1, EPI 2, EPI-3, ..., and one RV_ENDO contour named "septum", labelled by its attribute."""
    points, labels, slices = sample_shell(spacing=5.0, sax=tuple(range(-75, 80, 10)))
    curves = []
    for number in np.unique(slices):
        for label in np.unique(labels[slices == number]):
            copy = sum(contour_label == label for contour_label, _ in curves)
            name = label if copy == 0 else f"{label}{'-_ '[copy % 3]}{copy}"
            node = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", name)
            for point in points[(slices == number) & (labels == label)]:
                node.AddControlPoint(*map(float, point))
            curves.append((label, node))
    label, node = next((label, node) for label, node in curves[::-1] if label == "RV_ENDO")
    node.SetName("septum")
    node.SetAttribute(lib_contours.LABEL_ATTRIBUTE, label)
    return [node for _, node in curves]


def test_closed_curves_named_after_their_surfaces_mesh_the_domain(scene, logic):
    curves = shell_curves(scene)
    model = output_model(scene)
    logic.process(curves, model, cells=6000, domain=SHELL_DOMAIN, base_plane="none")
    assert_valid_domain(mesh_of(model), euler=6, components=1, measure=SHELL_VOLUME, measure_tolerance=0.03,
                        mean_quality=0.75)


def test_labelled_points_take_their_slices_from_curves_and_models(scene, logic):
    """Each closed curve is a slice of its own, a point list's points have none, a model's Slice ids are kept
    apart from the curves'; with no slice at all bitemesh finds the planes (None)."""
    curves = closed_curves(scene, levels=(-0.5, 0.5))
    for curve, name in zip(curves, ("LV_ENDO", "LV_ENDO_1")):
        curve.SetName(name)
    points = point_list(scene, sphere_points(20), "EPI 2")
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "labelled")
    model.SetAndObservePolyData(labelled_polydata(sphere_points(6), [7] * 6, [4, 4, 4, 9, 9, 9]))
    coordinates, labels, slices = lib_contours.labelledPoints([*curves, points, model])
    assert len(coordinates) == len(labels) == len(slices)
    assert set(labels.tolist()) == {"LV_ENDO", "EPI", "7"}
    assert slices[labels == "EPI"].tolist() == [-1] * 20 and slices[labels == "7"].tolist() == [6, 6, 6, 11, 11, 11]
    for number in (0, 1):   # each curve resampled evenly: at least its 12 control points, at most 5 mm apart
        contour = coordinates[slices == number]
        steps = np.linalg.norm(contour - np.roll(contour, 1, axis=0), axis=1)
        assert len(contour) >= 12 and steps.max() <= lib_contours.CONTOUR_SPACING
        assert steps.max() < 1.02 * steps.min() and set(labels[slices == number].tolist()) == {"LV_ENDO"}
    assert lib_contours.labelledPoints([points])[2] is None


@pytest.mark.parametrize("name, label", [("LV_ENDO", "LV_ENDO"), ("LV_ENDO_1", "LV_ENDO"), ("LV_ENDO 2", "LV_ENDO"),
                                         ("LV_ENDO-3", "LV_ENDO"), ("LV2", "LV2"), ("12", "12")])
def test_a_contour_is_labelled_by_its_name_without_a_copy_number(scene, name, label):
    assert lib_contours.contourLabel(scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", name)) == label


def test_bad_labelled_input_is_refused(scene, logic, tmp_path):
    curves = closed_curves(scene, levels=(-0.5, 0.0, 0.5))
    for curve in curves:
        curve.SetName("LV_ENDO")
    with pytest.raises(InvalidInputError, match="unknown surface 'RV_ENDO'; known surfaces: LV_ENDO"):
        logic.process(curves, output_model(scene), domain="LV_ENDO - RV_ENDO")
    fractional = scene.AddNewNodeByClass("vtkMRMLModelNode", "fractional labels")
    fractional.SetAndObservePolyData(nodes_to_polydata(sphere_points(30)))
    values = numpy_support.numpy_to_vtk(np.linspace(0.0, 2.0, 30), deep=True)
    values.SetName("Label")
    fractional.GetPolyData().GetPointData().AddArray(values)
    with pytest.raises(InvalidInputError, match="'fractional labels': the Label array holds non-integer numbers"):
        logic.process(fractional, output_model(scene))
    surface = scene.AddNewNodeByClass("vtkMRMLModelNode", "surface")
    surface.SetAndObservePolyData(nodes_to_polydata(sphere_points(30)))
    with pytest.raises(InvalidInputError, match="'surface' has no point array Label"):
        logic.process([curves[0], surface], output_model(scene), domain="LV_ENDO")
    segmentation, _, _ = ball_segmentation(scene, np.eye(3))
    with pytest.raises(InvalidInputError, match="clear domain to mesh the segment"):
        logic.process(segmentation, output_model(scene), domain="LV_ENDO")
    with pytest.raises(InvalidInputError, match="base_plane must be one of"):
        logic.process(curves, output_model(scene), domain="LV_ENDO", base_plane="top")
    with pytest.raises(InvalidInputError, match="labelled points"):
        logic.loadLabelledPoints(tmp_path / "missing.txt", scene=scene)
    with pytest.raises(InvalidInputError, match="coordinateSystem must be one of"):
        logic.loadLabelledPoints(GPFILE, scene=scene, coordinateSystem="IJK")


# --- bad input, cancel, progress ------------------------------------------------------------------------------------

def test_empty_point_list_is_refused(scene, logic):
    model = output_model(scene)
    with pytest.raises(InvalidInputError, match="no placed control points"):
        logic.process(scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", "empty"), model)
    assert model.GetMesh() is None


def test_negative_radius_is_refused(scene, logic):
    with pytest.raises(InvalidInputError, match=r"radius must be in \(0, inf\], got -2"):
        logic.process(point_list(scene, sphere_points(100)), output_model(scene), radius=-2.0)


@pytest.mark.parametrize("node_class, words", [
    ("vtkMRMLMarkupsCurveNode", "use a closed curve"),
    ("vtkMRMLScalarVolumeNode", "not an accepted input"),
])
def test_wrong_input_type_is_refused(scene, logic, node_class, words):
    with pytest.raises(InvalidInputError, match=words):
        logic.process(scene.AddNewNodeByClass(node_class), output_model(scene))


def test_bad_arguments_are_refused(scene, logic):
    points = point_list(scene, sphere_points(100))
    with pytest.raises(InvalidInputError, match="unknown parameter"):
        logic.process(points, output_model(scene), radiuss=3.0)
    with pytest.raises(InvalidInputError, match="method must be one of"):
        logic.process(points, output_model(scene), method="spline")
    with pytest.raises(InvalidInputError, match="no input node"):
        logic.process(None, output_model(scene))
    with pytest.raises(InvalidInputError, match="outputModelNode"):
        logic.process(points, None)
    with pytest.raises(InvalidInputError, match="not in a scene"):
        logic.process(points, slicer.vtkMRMLModelNode())
    with pytest.raises(InvalidInputError, match="no segments"):
        logic.process(scene.AddNewNodeByClass("vtkMRMLSegmentationNode"), output_model(scene))
    with pytest.raises(InvalidInputError, match="only input"):
        logic.process([points, scene.AddNewNodeByClass("vtkMRMLSegmentationNode")], output_model(scene))
    surface = output_model(scene)
    with pytest.raises(InvalidInputError, match="also the input"):
        logic.process(surface, surface)


def test_cancel_stops_and_writes_nothing(scene, logic):
    calls = []

    def progress(fraction, message):
        calls.append(fraction)
        if fraction > 0.3:
            raise Cancelled("the user pressed Cancel")

    model = output_model(scene)
    tables = scene.GetNumberOfNodesByClass("vtkMRMLTableNode")
    with pytest.raises(Cancelled):
        logic.process(point_list(scene, sphere_points(600)), model, radius=5.0, progress=progress)
    assert model.GetMesh() is None
    assert scene.GetNumberOfNodesByClass("vtkMRMLTableNode") == tables
    assert calls and max(calls) <= 0.5


def test_cancel_after_writing_is_too_late(scene, logic):
    """A cancel that arrives once the mesh is written does not pretend that nothing was written."""
    def progress(fraction, message):
        if fraction == 1.0:
            raise Cancelled("the user pressed Cancel")

    model = output_model(scene)
    logic.process(point_list(scene, sphere_points(600)), model, radius=5.0, progress=progress)
    assert model.GetMesh().GetNumberOfCells() > 100


def test_progress_goes_from_0_to_1(scene, logic):
    reports = []
    logic.process(point_list(scene, sphere_points(600)), output_model(scene), radius=5.0,
                  progress=lambda fraction, message: reports.append((fraction, message)))
    fractions = [fraction for fraction, _ in reports]
    assert fractions[0] == 0.0 and fractions[-1] == 1.0
    assert all(0.0 <= fraction <= 1.0 for fraction in fractions)
    assert all(isinstance(message, str) for _, message in reports)


# --- parameters, requirements, the module's files -------------------------------------------------------------------

def test_parameter_specs_follow_the_core_dataclasses():
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs()}
    assert list(specs) == list(lib_parameters.PARAMETERS)
    from bitemesh.core.parameters import FidelityParameters, OptimizeSwitch
    classes = {cls.__name__: cls for cls in (ImplicitParameters, BitingParameters, SpuriousParameters,
                                             QualityParameters, OptimizeSwitch, LabelledParameters,
                                             FidelityParameters)}
    for name, (dataclass_name, field_name) in lib_parameters.PARAMETERS.items():
        item = {f.name: f for f in fields(classes[dataclass_name])}[field_name]
        spec = specs[name]
        assert spec.core == field_name and spec.help == item.metadata["help"]
        if "choices" in item.metadata:
            assert spec.choices == item.metadata["choices"] and spec.default == item.default
        elif item.metadata.get("text"):
            assert spec.kind is str and spec.choices is None and spec.default == item.default
        else:
            low, high, low_open, _ = item.metadata["range"]
            assert spec.low == low and spec.lowOpen == low_open
            assert spec.high == (None if high is None or high == float("inf") else high)
            assert (spec.automatic is not None) == (item.default is None)
    assert specs["radius"].automatic == 0.0 and specs["radius"].kind is float
    assert specs["cells"].kind is int and specs["cells"].default == 10000
    assert (specs["threshold"].low, specs["threshold"].high) == (0.0, 1.0)
    assert specs["method"].choices == ("mpu", "rbf")
    assert (specs["domain"].kind, specs["domain"].default, specs["domain"].choices) == (str, "", None)
    assert specs["basePlane"].choices == ("auto", "valves", "none") and specs["basePlane"].default == "auto"
    # "automatic" is never a valid value of the core, so it cannot be confused with one
    for spec in specs.values():
        if spec.automatic is not None:
            with pytest.raises(InvalidInputError):
                classes[lib_parameters.PARAMETERS[spec.name][0]](**{spec.core: spec.automatic})
    assert lib_parameters.coreParameters({"radius": 0.0, "gridSpacing": 0.5, "method": "rbf", "cells": 500}) == \
        {"radius": None, "grid_spacing": 0.5, "method": "rbf", "cells": 500}
    assert lib_parameters.coreParameters({"domain": "EPI - LV_ENDO", "basePlane": "none"}) == \
        {"domain": "EPI - LV_ENDO", "base_plane": "none"}


def test_requirements_install_only_scipy(monkeypatch):
    import importlib.util
    calls = []
    assert lib_requirements.missingRequirements() == []
    assert lib_requirements.installRequirements(pipInstall=calls.append) == [] and calls == []

    real_find_spec = importlib.util.find_spec
    state = {"installed": False}

    def find_spec(name, *arguments):
        if name == "scipy" and not state["installed"]:
            return None
        return real_find_spec(name, *arguments)

    def pip(requirements):
        calls.append(list(requirements))
        state["installed"] = True

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    assert lib_requirements.missingRequirements() == ["scipy>=1.9"]
    with pytest.raises(lib_requirements.MissingRequirementError, match="not installed"):
        lib_requirements.installRequirements(pipInstall=pip, confirm=lambda missing: False)
    assert calls == []
    assert lib_requirements.installRequirements(pipInstall=pip) == ["scipy>=1.9"]
    assert calls == [["scipy>=1.9", f"numpy=={np.__version__}"]]   # numpy pinned as bundled, never upgraded
    assert not any(name in " ".join(calls[0]).lower() for name in ("vtk", "simpleitk", "itk"))


def test_ui_file_binds_every_parameter():
    tree = ElementTree.parse(MODULE / "Resources" / "UI" / "BiteMesh.ui")
    bound = {}
    for widget in tree.iter("widget"):
        for prop in widget.findall("property"):
            if prop.get("name") == "SlicerParameterName":
                bound[prop.find("string").text] = widget.get("class")
    assert set(lib_parameters.PARAMETERS) <= set(bound)
    assert set(bound) - set(lib_parameters.PARAMETERS) == {"inputNode", "outputModel"}
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs()}
    for name, widget_class in bound.items():
        spec = specs.get(name)
        expected = ("qMRMLNodeComboBox" if spec is None else "QComboBox" if spec.choices else
                    "QLineEdit" if spec.kind is str else "QSpinBox" if spec.kind is int else "QDoubleSpinBox")
        assert widget_class == expected, name   # the widget types parameterNodeWrapper connects
    names = {widget.get("name") for widget in tree.iter("widget")}
    assert {"applyButton", "cancelButton", "progressBar", "segmentComboBox", "contoursSelector",
            "loadLabelledPointsButton"} <= names


def test_module_file_has_the_slicer_classes():
    source = (MODULE / "BiteMesh.py").read_text()
    module = ast.parse(source)
    classes = {node.name: [ast.unparse(base) for base in node.bases] for node in module.body
               if isinstance(node, ast.ClassDef)}
    assert classes["BiteMesh"] == ["ScriptedLoadableModule"]
    assert "ScriptedLoadableModuleWidget" in classes["BiteMeshWidget"]
    assert classes["BiteMeshTest"] == ["ScriptedLoadableModuleTest"]
    assert "from BiteMeshLib.logic import" in source and "BiteMeshLogic" in source
    assert "tryWithErrorDisplay" in source and "print(" not in source
    assert issubclass(BiteMeshLogic, bitemesh_logic.ScriptedLoadableModuleLogic)


def test_self_test_cases_pass_headless(scene, logic):
    """The cases BiteMeshTest runs in Slicer, on a slicer-core scene."""
    for case in selftest.CASES:
        case(scene, logic)


RUN_FROM_LAYOUT = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np, slicer
from BiteMeshLib.logic import BiteMeshLogic
import bitemesh
scene = slicer.vtkMRMLScene()
points = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode")
directions = np.random.default_rng(0).normal(size=(400, 3))
for point in 10 * directions / np.linalg.norm(directions, axis=1, keepdims=True):
    points.AddControlPoint(*map(float, point))
model = scene.AddNewNodeByClass("vtkMRMLModelNode")
result = BiteMeshLogic().process(points, model, radius=3.0)
print(bitemesh.__file__)
print(model.GetMesh().GetNumberOfCells())
"""


def run_module(module_dir, cwd):
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    completed = subprocess.run([sys.executable, "-c", RUN_FROM_LAYOUT, str(module_dir)], cwd=cwd, env=environment,
                               capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stderr
    where, cells = completed.stdout.split()[-2:]
    assert int(cells) > 100
    return Path(where)


def test_extension_layout_ships_bitemesh(tmp_path):
    """As installed by the extension: BiteMesh.py, BiteMeshLib/ and bitemesh/ side by side (no PYTHONPATH)."""
    lib = tmp_path / "lib" / "Slicer-5.8" / "qt-scripted-modules"
    shutil.copytree(MODULE / "BiteMeshLib", lib / "BiteMeshLib", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(MODULE / "BiteMesh.py", lib)
    package = Path(bitemesh.__file__).parent
    shutil.copytree(package, lib / "bitemesh", ignore=shutil.ignore_patterns("__pycache__", "cli"))
    assert run_module(lib, tmp_path) == lib / "bitemesh" / "__init__.py"


def test_checkout_layout_finds_filters(tmp_path):
    """As added to Slicer's module paths from a checkout: bitemesh found in filters/ beside slicer_module/."""
    where = run_module(MODULE, tmp_path)
    assert where == MODULE.parents[1] / "filters" / "bitemesh" / "__init__.py"


LOAD_MODULE_FILE = """
import sys, types, typing
# Stand-ins for what only the Slicer application has (Qt, ScriptedLoadableModule, parameterNodeWrapper).
sys.modules["qt"] = types.ModuleType("qt")
scripted = types.ModuleType("slicer.ScriptedLoadableModule")
for name in ("ScriptedLoadableModule", "ScriptedLoadableModuleWidget", "ScriptedLoadableModuleTest",
             "ScriptedLoadableModuleLogic"):
    setattr(scripted, name, type(name, (), {"__init__": lambda self, parent=None: setattr(self, "parent", parent)}))
sys.modules["slicer.ScriptedLoadableModule"] = scripted
wrapper = types.ModuleType("slicer.parameterNodeWrapper")
class Validator:
    def __init__(self, *arguments):
        self.arguments = arguments
class Choice(Validator):
    def validate(self, value):
        assert value in self.arguments[0], value
class Minimum(Validator):
    def validate(self, value):
        assert value >= self.arguments[0], value
class WithinRange(Validator):
    def validate(self, value):
        assert self.arguments[0] <= value <= self.arguments[1], value
wrapper.Choice, wrapper.Minimum, wrapper.WithinRange = Choice, Minimum, WithinRange
wrapper.parameterNodeWrapper = lambda cls: cls
sys.modules["slicer.parameterNodeWrapper"] = wrapper
import slicer
slicer.parameterNodeWrapper = wrapper
sys.path.insert(0, sys.argv[1])
import BiteMesh

module = BiteMesh.BiteMesh(types.SimpleNamespace())
assert module.parent.title == "BiteMesh" and module.parent.categories
cls = BiteMesh.parameterNodeClass()
hints = typing.get_type_hints(cls, include_extras=True)
assert type(None) in typing.get_args(hints["inputNode"]), "inputNode must allow None"
assert typing.get_args(hints["contours"])[0] is slicer.vtkMRMLMarkupsClosedCurveNode
for spec in BiteMesh.BiteMeshLogic.parameterSpecs():
    kind, *validators = typing.get_args(hints[spec.name]) or (hints[spec.name],)   # free text: plain str
    assert kind is spec.kind, spec.name
    for validator in validators:
        validator.validate(getattr(cls, spec.name))   # every default passes its own range
    if kind is int:
        assert all(max(validator.arguments) <= 2**31 - 1 for validator in validators), spec.name
print(sorted(hints))
"""


def test_module_file_builds_its_parameter_node_class():
    """BiteMesh.py loads (with stand-ins for Qt and the wrapper) and its parameter node follows the specs."""
    completed = subprocess.run([sys.executable, "-c", LOAD_MODULE_FILE, str(MODULE)], capture_output=True,
                               text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr
    names = ast.literal_eval(completed.stdout.strip().splitlines()[-1])
    assert set(names) == set(lib_parameters.PARAMETERS) | {"inputNode", "contours", "segmentId", "outputModel"}


def test_optimize_runs_the_mesh_optimizer_like_bitemesh_run(scene, logic):
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters, SpuriousParameters
    from bitemesh.core.pipeline import run
    points = sphere_points()
    model = output_model(scene)
    result = logic.process(point_list(scene, points), model, cells=2000, optimize=1)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, mean_quality=0.85)
    expected = run(points, None, ImplicitParameters(), BitingParameters(cells=2000), SpuriousParameters(),
                   optimize=OptimizeParameters()).mesh
    assert result.summary.q_mean >= 0.85 and len(mesh.cells) == len(expected.cells)


@pytest.mark.slow
def test_a_gpfile_as_real_exports_write_it_meshes_as_run_labelled(scene, logic, tmp_path):
    """Denser contours, no RV epicardium, no outflow valves, 'sliceID' and time frame 1: loaded and meshed with the
    panel's defaults (R = 2 mm for biv-me labels), the RV epicardium derived, as run_labelled does."""
    from tests.cardiac_variants import variant_file
    path = variant_file(GPFILE, "like GPFile of issue 10", tmp_path)
    node = logic.loadLabelledPoints(path, scene=scene)
    points, labels, slices = read_labelled_points(path)
    model = output_model(scene)
    result = logic.process(node, model)
    expected = run_labelled(points * [-1.0, -1.0, 1.0], labels, slices=slices)
    np.testing.assert_array_equal(mesh_of(model).cells, expected.mesh.cells)
    assert result.radius == 2.0 and any("RV epicardium is derived" in note for note in result.notes)
