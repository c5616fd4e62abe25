"""BiteMeshLogic on labelled contours: a loaded GPFile meshed as run_labelled meshes it (as shipped and as real
exports write it), closed curves named after their surfaces, slices from curves and models, labels from names,
bad labelled input refused.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import InvalidInputError
from bitemesh.convert import nodes_to_polydata, point_coordinates
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.parameters import BitingParameters
from bitemesh.io import read_labelled_points
from vtkmodules.util import numpy_support

from tests.builders import SHELL_DOMAIN, SHELL_VOLUME, closed_shell_contours, labelled_polydata
from tests.meshcheck import assert_valid_domain
from tests.slicer.scenes import (GPFILE, ball_segmentation, closed_curves, mesh_of, output_model, point_list,
                                 sphere_points)
from BiteMeshLib import contours as lib_contours  # on sys.path from tests.slicer.scenes


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
    points, labels, slices = closed_shell_contours()
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
