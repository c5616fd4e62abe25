"""BiteMeshLogic.fitTemplate: the demo heart meshed in the scene (20,000 cells, optimizer off) is the template;
another frame of the cine cycle, loaded as labelled points, is the data: the output model holds the template's
cells on moved points within the issue's accuracy (wall guide points mean <= 1.0 mm, 95 % <= 3.0 mm), with one
surface model a tag as Apply makes them; a node that is no BiteMesh mesh is refused naming templateNode.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import InvalidInputError
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.sources.contours.cardiac import BIVME_SURFACES, canonical_labels
from bitemesh.core.sources.contours.registration import registered
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.io import read_labelled_points

from tests.conftest import DATA
from tests.slicer.scenes import GPFILE, mesh_of, output_model

CINE_FRAME = DATA / "bivme_patient1_cine" / "guidepoints" / "GPFile_008.txt"
WALL_WORDS = ("ENDOCARDIAL", "EPICARDIAL", "FREEWALL", "SEPTUM")


def test_the_heart_fitted_to_end_systole_keeps_its_cells_and_surfaces(scene, logic):
    if not CINE_FRAME.is_file():
        pytest.skip(f"{CINE_FRAME} is absent")
    template = output_model(scene, "template")
    logic.process(logic.loadLabelledPoints(GPFILE, scene=scene), template, cells=20000, optimize=0)
    data = logic.loadLabelledPoints(CINE_FRAME, scene=scene)
    fitted = output_model(scene, "systole")
    result = logic.fitTemplate(template, data, fitted)
    before, after = mesh_of(template), mesh_of(fitted)
    np.testing.assert_array_equal(after.cells, before.cells)
    np.testing.assert_allclose(after.points, result.mesh.points, rtol=0, atol=1e-9)
    points, labels, slices = read_labelled_points(CINE_FRAME)   # where the fit takes them: the slices registered
    points, labels, _, _ = registered(points, canonical_labels(labels)[0], slices, BIVME_SURFACES)
    points = points * [-1.0, -1.0, 1.0]   # loadLabelledPoints reads LPS into Slicer's RAS
    wall = np.array([any(word in label for word in WALL_WORDS) for label in labels])
    distance = distances_to_facets(points[wall], after.points[boundary_facets(after.cells)])
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0
    names = [fitted.GetNthNodeReference("BiteMeshSurface", i).GetName()
             for i in range(fitted.GetNumberOfNodeReferences("BiteMeshSurface"))]
    assert names == [f"systole {name}" for name in ("EPI", "LV_ENDO", "RV_ENDO", "BASE")]


def test_a_template_that_is_no_bitemesh_mesh_is_refused(scene, logic):
    data = logic.loadLabelledPoints(GPFILE, scene=scene)
    with pytest.raises(InvalidInputError, match="templateNode"):
        logic.fitTemplate(output_model(scene, "empty"), data, output_model(scene, "out"))
