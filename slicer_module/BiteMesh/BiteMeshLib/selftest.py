"""Sample inputs and the module's self-test cases, on any MRML scene (Slicer's, or a slicer-core one in pytest).

``BiteMeshTest`` in BiteMesh.py runs these cases on ``slicer.mrmlScene``; tests/slicer runs them headless too.
"""
from __future__ import annotations

import numpy as np
import slicer
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonMath import vtkMatrix4x4

#: the sample sphere and ball: centre (RAS, mm), radius (mm); off the origin so that a wrong frame shows.
CENTRE = np.array([30.0, -40.0, 55.0])
RADIUS = 20.0


def sphereSamples(count: int = 1500, centre=CENTRE, radius: float = RADIUS, seed: int = 1) -> np.ndarray:
    """(count, 3) points on a sphere (RAS, mm), seeded."""
    directions = np.random.default_rng(seed).normal(size=(count, 3))
    return np.asarray(centre) + radius * directions / np.linalg.norm(directions, axis=1, keepdims=True)


def addPointList(scene, points, name: str = "sphere points"):
    """A markups point list holding ``points`` (RAS)."""
    node = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", name)
    for point in points:
        node.AddControlPoint(*map(float, point))
    return node


def addClosedCurves(scene, centre=CENTRE, radius: float = RADIUS, levels=(-0.75, -0.4, 0.0, 0.4, 0.75),
                    controlPoints: int = 12):
    """Circles of a sphere on parallel axial planes (sparse contours), one closed curve node each."""
    nodes = []
    angles = np.linspace(0, 2 * np.pi, controlPoints, endpoint=False)
    for index, level in enumerate(levels):
        ring = radius * np.sqrt(1 - level**2)
        node = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", f"contour {index}")
        for angle in angles:
            node.AddControlPoint(centre[0] + ring * np.cos(angle), centre[1] + ring * np.sin(angle),
                                 centre[2] + radius * level)
        nodes.append(node)
    return nodes


def addBallSegmentation(scene, radius: float = 12.0, spacing=(0.8, 0.6, 1.2), origin=(10.0, -20.0, 5.0),
                        direction=((-1, 0, 0), (0, -1, 0), (0, 0, 1)), dims=(40, 50, 28)):
    """A segmentation with one ball segment, imported from a label map with the given geometry.

    Returns the segmentation node and the ball's centre in RAS (from the label map's IJK-to-RAS).
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    labelmap = scene.AddNewNodeByClass("vtkMRMLLabelMapVolumeNode", "ball labelmap")
    labelmap.SetSpacing(*spacing)
    labelmap.SetOrigin(*origin)
    matrix = vtkMatrix4x4()
    for row in range(3):
        for column in range(3):
            matrix.SetElement(row, column, float(direction[row][column]))
    labelmap.SetIJKToRASDirectionMatrix(matrix)
    centreIjk = (np.asarray(dims) - 1) / 2.0
    i, j, k = np.meshgrid(*[np.arange(n) for n in dims], indexing="ij")
    inside = np.sqrt(((i - centreIjk[0]) * spacing[0]) ** 2 + ((j - centreIjk[1]) * spacing[1]) ** 2
                     + ((k - centreIjk[2]) * spacing[2]) ** 2) < radius
    image = vtkImageData()
    image.SetDimensions(*dims)
    values = numpy_support.numpy_to_vtk((inside * 7).astype(np.uint8).ravel(order="F"), deep=True)
    image.GetPointData().SetScalars(values)
    labelmap.SetAndObserveImageData(image)
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode", "ball segmentation")
    if not slicer.vtkSlicerSegmentationsModuleLogic.ImportLabelmapToSegmentationNode(labelmap, segmentation):
        raise RuntimeError("importing the label map into the segmentation failed")
    ijkToRas = vtkMatrix4x4()
    labelmap.GetIJKToRASMatrix(ijkToRas)
    centre = np.array(ijkToRas.MultiplyPoint([*centreIjk, 1.0])[:3])
    scene.RemoveNode(labelmap)
    return segmentation, centre


def meshOf(modelNode):
    """The bitemesh Mesh held by a model node."""
    from bitemesh.convert import unstructured_to_mesh
    return unstructured_to_mesh(modelNode.GetMesh())


def centroid(mesh) -> np.ndarray:
    """Volume-weighted centroid of a tetrahedral mesh."""
    corners = mesh.points[mesh.cells]
    volumes = np.linalg.det(corners[:, 1:] - corners[:, :1]) / 6.0
    return (corners.mean(axis=1) * volumes[:, None]).sum(axis=0) / volumes.sum()


def _check(condition: bool, message: str) -> None:
    if not condition:
        raise AssertionError(message)


def _checkMesh(mesh, centre, volume, *, centreTolerance: float, volumeTolerance: float) -> None:
    from bitemesh.core.mesh.validity import check_valid_domain
    problems = check_valid_domain(mesh)
    _check(problems == [], f"invalid mesh: {problems}")
    _check(mesh.cells.shape[1] == 4, "the mesh is not tetrahedral")
    offset = float(np.linalg.norm(centroid(mesh) - centre))
    _check(offset < centreTolerance, f"mesh centroid {centroid(mesh)} is {offset:.2f} mm from {centre}")
    measured = float(mesh.cell_data["Volume"].sum())
    _check(abs(measured / volume - 1) < volumeTolerance, f"mesh volume {measured:.0f} mm3, expected {volume:.0f}")


def runPointsCase(scene, logic) -> None:
    """Points on a sphere (RAS, off the origin) -> a valid tetrahedral model at the sphere, with its histogram."""
    points = addPointList(scene, sphereSamples())
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "sphere mesh")
    result = logic.process(points, model, cells=3000)
    mesh = meshOf(model)
    _checkMesh(mesh, CENTRE, 4 / 3 * np.pi * RADIUS**3, centreTolerance=0.5, volumeTolerance=0.05)
    _check(result.tableNode.GetNumberOfRows() == 20, "the histogram table should have 20 bins")
    _check(result.chartNode.GetNumberOfPlotSeriesNodes() == 1, "the chart should show one series")


def runSegmentationCase(scene, logic) -> None:
    """A ball segment of a label map with LPS-like directions -> tetrahedra where the segment is (RAS)."""
    segmentation, centre = addBallSegmentation(scene)
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "ball mesh")
    logic.process(segmentation, model, cells=3000)
    _checkMesh(meshOf(model), centre, 4 / 3 * np.pi * 12.0**3, centreTolerance=0.5, volumeTolerance=0.05)


def runErrorsCase(scene, logic) -> None:
    """Bad input raises bitemesh's InvalidInputError naming what is wrong."""
    from bitemesh import InvalidInputError
    empty = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", "empty")
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "no mesh")
    for node, parameters, words in ((empty, {}, "control points"),
                                    (addPointList(scene, sphereSamples(200)), {"radius": -1.0}, "radius")):
        try:
            logic.process(node, model, **parameters)
        except InvalidInputError as error:
            _check(words in str(error), f"the message {error} should mention {words}")
        else:
            raise AssertionError(f"no error for {parameters or 'an empty point list'}")
    _check(model.GetMesh() is None, "a failed run must leave the output model empty")


CASES = (runPointsCase, runSegmentationCase, runErrorsCase)
