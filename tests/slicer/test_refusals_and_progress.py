"""BiteMeshLogic refuses bad input and arguments with the parameter's name, stops on cancel without writing
(or says a late cancel came too late), and reports progress from 0 to 1.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import pytest
from bitemesh import Cancelled, InvalidInputError

from tests.slicer.scenes import output_model, point_list, slicer, sphere_points


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
