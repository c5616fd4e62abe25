"""BiteMeshLogic's surface models: one model node per surface tag of the mesh's boundary, named by the tag and
coloured apart (the demo heart's EPI, LV_ENDO, RV_ENDO and BASE), reused and pruned by the next run, and the tags
carried through a segmentation's reflecting parent transform.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import numpy as np
from bitemesh.convert import point_coordinates, tag_names_of
from bitemesh.core.mesh.topology import boundary_facets
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonMath import vtkMatrix4x4

from tests.meshcheck import assert_tagged, oriented_rows
from tests.slicer.scenes import GPFILE, ball_segmentation, mesh_of, output_model, point_list, sphere_points
from BiteMeshLib.outputs import SURFACE_COLOURS, SURFACE_ROLE  # on sys.path from tests.slicer.scenes


def surfaces_of(model) -> list:
    return [model.GetNthNodeReference(SURFACE_ROLE, i) for i in range(model.GetNumberOfNodeReferences(SURFACE_ROLE))]


def triangles(node) -> np.ndarray:
    polys = node.GetPolyData().GetPolys()
    return numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)


def test_the_heart_gives_one_model_per_named_surface_and_a_points_run_prunes_them(scene, logic):
    node = logic.loadLabelledPoints(GPFILE, scene=scene)
    model = output_model(scene, "heart")
    result = logic.process(node, model, cells=20000, optimize=0)
    mesh = mesh_of(model)
    names = ["EPI", "LV_ENDO", "RV_ENDO", "BASE"]
    assert [surface.GetName() for surface in result.surfaceNodes] == [f"heart {name}" for name in names]
    assert surfaces_of(model) == result.surfaceNodes
    colours = {surface.GetDisplayNode().GetColor() for surface in result.surfaceNodes}
    assert colours == {tuple(colour) for colour in SURFACE_COLOURS[:4]}   # four colours, one a surface
    # together, the surfaces are the boundary, each triangle once, on the mesh's points
    every = np.vstack([triangles(surface) for surface in result.surfaceNodes])
    assert oriented_rows(every) == oriented_rows(boundary_facets(mesh.cells)) and len(every) == len(set(map(
        tuple, np.sort(every, axis=1).tolist())))
    for tag, (surface, name) in enumerate(zip(result.surfaceNodes, names), start=1):
        assert surface.GetAttribute("BiteMesh.SurfaceTag") == str(tag)
        assert tag_names_of(surface.GetPolyData()) == {name: (tag, 2)}
        np.testing.assert_array_equal(point_coordinates(surface.GetPolyData()), mesh.points)
    # a run on scattered points into the same model reuses the first node and removes the other three
    ids = [surface.GetID() for surface in result.surfaceNodes]
    again = logic.process(point_list(scene, sphere_points()), model, cells=2000, optimize=0)
    assert [surface.GetID() for surface in again.surfaceNodes] == ids[:1]
    assert again.surfaceNodes[0].GetName() == "heart BOUNDARY_1"
    assert all(scene.GetNodeByID(removed) is None for removed in ids[1:])


def test_a_segment_under_a_reflecting_transform_keeps_its_tags_facing_out(scene, logic):
    segmentation, _, _ = ball_segmentation(scene, np.eye(3))
    mirror = scene.AddNewNodeByClass("vtkMRMLLinearTransformNode")
    matrix = vtkMatrix4x4()
    matrix.SetElement(0, 0, -1.0)
    mirror.SetMatrixTransformToParent(matrix)
    segmentation.SetAndObserveTransformNodeID(mirror.GetID())
    model = output_model(scene)
    result = logic.process(segmentation, model, cells=2000, optimize=0)
    assert [surface.GetName() for surface in result.surfaceNodes] == ["mesh BOUNDARY_1"]
    mesh = mesh_of(model)
    np.testing.assert_array_equal(mesh.cells, result.mesh.cells)
    assert_tagged(result.mesh)   # the facets face out of the mirrored mesh, as its cells are positive again
    np.testing.assert_array_equal(triangles(result.surfaceNodes[0]), result.mesh.facets)
    assert result.mesh.tag_names == {"BOUNDARY_1": (1, 2), "REGION_1": (1, 3)}
    assert (mesh.cell_data["Region"] == 1).all()
