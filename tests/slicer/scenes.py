"""What the Slicer tests build in an MRML scene (slicer-core's real MRML classes): point lists, closed curves, output
models, labelmap segmentations with one ball or more; the mesh a model holds; and the module's BiteMeshLib, put on
sys.path from slicer_module/BiteMesh.

Importing this module skips the importing test module where slicer-core is absent (the main environment).
"""
from __future__ import annotations

from pathlib import Path

import bitemesh
import numpy as np
import pytest
from bitemesh.convert import cell_types, unstructured_to_mesh
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import VTK_TETRA, vtkImageData
from vtkmodules.vtkCommonMath import vtkMatrix4x4

slicer = pytest.importorskip("slicer")
if not hasattr(slicer, "vtkMRMLScene"):   # PyPI also has an unrelated package named "slicer"
    pytest.skip("the 'slicer' module found is not slicer-core (no vtkMRMLScene)", allow_module_level=True)

from tests.slicer.module import MODULE  # noqa: E402 - puts the module's folder on sys.path
from BiteMeshLib.logic import BiteMeshLogic  # noqa: E402

CENTRE = np.array([30.0, -40.0, 55.0])   # RAS, mm: off the origin, so that a wrong frame shows
GPFILE = Path(bitemesh.__file__).resolve().parent / "data" / "bivme_patient1" / "GPFile_000.txt"
RADIUS = 20.0
BALL_RADIUS = 12.0

__all__ = ["BALL_RADIUS", "BiteMeshLogic", "CENTRE", "GPFILE", "MODULE", "RADIUS", "ball_segmentation",
           "closed_curves", "labelmap_segmentation", "mesh_of", "output_model", "point_list", "slicer",
           "sphere_points", "translation"]


def sphere_points(count=1500, seed=1):
    """``count`` random points on the sphere of radius RADIUS about CENTRE."""
    directions = np.random.default_rng(seed).normal(size=(count, 3))
    return CENTRE + RADIUS * directions / np.linalg.norm(directions, axis=1, keepdims=True)


def point_list(scene, points, name="points"):
    """A markups point list of ``points``."""
    node = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", name)
    for point in points:
        node.AddControlPoint(*map(float, point))
    return node


def output_model(scene, name="mesh"):
    return scene.AddNewNodeByClass("vtkMRMLModelNode", name)


def mesh_of(model):
    """The model's tetrahedra as a bitemesh Mesh (after checking they are all tetrahedra)."""
    grid = model.GetMesh()
    assert grid is not None and grid.IsA("vtkUnstructuredGrid")
    assert set(cell_types(grid).tolist()) == {VTK_TETRA}
    return unstructured_to_mesh(grid)


def translation(scene, shift) -> object:
    """A linear transform node that moves its children by ``shift`` (3,) mm."""
    transform = scene.AddNewNodeByClass("vtkMRMLLinearTransformNode")
    matrix = vtkMatrix4x4()
    for axis in range(3):
        matrix.SetElement(axis, 3, float(shift[axis]))
    transform.SetMatrixTransformToParent(matrix)
    return transform


def labelmap_segmentation(scene, direction, balls, spacing=(0.8, 0.6, 1.2), origin=(10.0, -20.0, 5.0),
                          dims=(40, 50, 28), name="ball"):
    """A segmentation imported from a label map with the given geometry holding ``balls``, each (centre IJK, radius
    mm, label): one segment per label.  Returns the segmentation node and, per ball, its RAS centre and the volume
    of its voxels."""
    spacing = np.asarray(spacing)
    labelmap = scene.AddNewNodeByClass("vtkMRMLLabelMapVolumeNode", name)
    labelmap.SetSpacing(*spacing)
    labelmap.SetOrigin(*origin)
    matrix = vtkMatrix4x4()
    for row in range(3):
        for column in range(3):
            matrix.SetElement(row, column, float(direction[row, column]))
    labelmap.SetIJKToRASDirectionMatrix(matrix)
    index = np.stack(np.meshgrid(*[np.arange(n) for n in dims], indexing="ij"), axis=-1)
    labels = np.zeros(dims, dtype=np.uint8)
    ijk_to_ras = vtkMatrix4x4()
    labelmap.GetIJKToRASMatrix(ijk_to_ras)
    placed = []
    for centre_ijk, radius, label in balls:
        inside = np.linalg.norm((index - np.asarray(centre_ijk, float)) * spacing, axis=-1) < radius
        assert not labels[inside].any(), "the balls overlap"
        labels[inside] = label
        placed.append((np.array(ijk_to_ras.MultiplyPoint([*map(float, centre_ijk), 1.0])[:3]),
                       inside.sum() * np.prod(spacing)))
    image = vtkImageData()
    image.SetDimensions(*dims)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(labels.ravel(order="F"), deep=True))
    labelmap.SetAndObserveImageData(image)
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode", "segmentation")
    assert slicer.vtkSlicerSegmentationsModuleLogic.ImportLabelmapToSegmentationNode(labelmap, segmentation)
    return segmentation, placed


def ball_segmentation(scene, direction, spacing=(0.8, 0.6, 1.2), origin=(10.0, -20.0, 5.0), dims=(40, 50, 28)):
    """A ball segment (radius BALL_RADIUS) imported from a label map with the given geometry; returns it, the ball's
    RAS centre and its voxel volume."""
    segmentation, [(centre, voxel_volume)] = labelmap_segmentation(
        scene, direction, [((18.0, 27.0, 13.0), BALL_RADIUS, 5)], spacing, origin, dims)
    return segmentation, centre, voxel_volume


def closed_curves(scene, levels=(-0.75, -0.4, 0.0, 0.4, 0.75), control_points=12):
    """Closed curves on the sphere of radius RADIUS about CENTRE, one per level (z / RADIUS), in planes z = const."""
    nodes = []
    for index, level in enumerate(levels):
        ring = RADIUS * np.sqrt(1 - level**2)
        node = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", f"contour {index}")
        for angle in np.linspace(0, 2 * np.pi, control_points, endpoint=False):
            node.AddControlPoint(CENTRE[0] + ring * np.cos(angle), CENTRE[1] + ring * np.sin(angle),
                                 CENTRE[2] + RADIUS * level)
        nodes.append(node)
    return nodes
