"""BiteMeshLogic on segmentations: the tetrahedra where the segment is (rotated and reflected label maps, a parent
transform, a closed-surface segment), the optimizer in place, a segment chosen by its id.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import InvalidInputError
from vtkmodules.vtkCommonCore import VTK_SHORT
from vtkmodules.vtkCommonDataModel import vtkImageData

from tests.builders import rotation, vtk_sphere
from tests.meshcheck import assert_valid_domain, centroid
from tests.slicer.scenes import (BALL_RADIUS, CENTRE, ball_segmentation, labelmap_segmentation, mesh_of, output_model,
                                 slicer, translation)


# --- segmentation ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("direction", [
    pytest.param(np.diag([-1.0, -1.0, 1.0]) @ rotation([0.0, 0.0, 1.0], 30), id="rotated"),
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
    segmentation.AddSegmentFromClosedSurfaceRepresentation(vtk_sphere(BALL_RADIUS, (64, 64), CENTRE), "ball",
                                                        [1.0, 0.0, 0.0])
    model = output_model(scene)
    logic.process(segmentation, model, cells=3000)
    mesh = mesh_of(model)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * BALL_RADIUS**3, measure_tolerance=0.05)
    assert np.linalg.norm(centroid(mesh) - CENTRE) < 0.5


#: two balls of one label map, far apart: (centre IJK, radius mm, label)
TWO_BALLS = [((18.0, 27.0, 13.0), BALL_RADIUS, 5), ((62.0, 27.0, 13.0), 8.0, 7)]


def test_segment_is_chosen_by_id(scene, logic):
    """Two segments, balls of radii 12 and 8 mm 35 mm apart: the second, chosen by its id, is meshed (its volume and
    centre) and nothing of the first; without an id the first is meshed; an unknown id is refused."""
    segmentation, balls = labelmap_segmentation(scene, np.eye(3), TWO_BALLS, dims=(80, 50, 28))
    segments = segmentation.GetSegmentation()
    ids = [segments.GetNthSegmentID(i) for i in range(segments.GetNumberOfSegments())]
    by_label = {segments.GetSegment(segment).GetLabelValue(): segment for segment in ids}
    assert len(ids) == 2 and sorted(by_label) == [5, 7]
    with pytest.raises(InvalidInputError, match="'nope' is not a segment"):
        logic.process(segmentation, output_model(scene), segmentId="nope")

    (first_centre, _), (second_centre, _) = balls
    model = output_model(scene)
    result = logic.process(segmentation, model, segmentId=by_label[7], cells=3000)
    mesh = mesh_of(model)
    assert result.mesh.cells.shape == mesh.cells.shape
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * 8.0**3, measure_tolerance=0.05)
    assert np.linalg.norm(centroid(mesh) - second_centre) < 0.5
    assert np.linalg.norm(mesh.points - second_centre, axis=1).max() < 8.0 + 1.0   # nothing of the first ball
    assert np.linalg.norm(mesh.points - first_centre, axis=1).min() > BALL_RADIUS

    default = output_model(scene)
    logic.process(segmentation, default, radius=3.0)   # no id: the first segment
    first = mesh_of(default)
    assert np.linalg.norm(centroid(first) - first_centre) < 0.5
    assert np.linalg.norm(first.points - first_centre, axis=1).max() < BALL_RADIUS + 1.0
