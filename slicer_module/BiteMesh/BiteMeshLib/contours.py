"""Labelled contour points: biv-me GPFiles and tables loaded as model nodes, and the labelled points of models,
closed curves and point lists named after their surfaces."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import slicer
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkStringArray

from .points import closedCurvePoints, closedLength, pointListPoints, resampleClosed, worldPolyData
from .requirements import requireBitemesh

#: how loadLabelledPoints takes a file's coordinates: as LPS (negate x and y for RAS) or as RAS.
COORDINATE_SYSTEMS = ("LPS", "RAS")
#: the loaded points are drawn as dots this large (pixels).
LABELLED_POINT_SIZE = 4.0
#: a labelled closed curve is resampled evenly by arc length to at least its control points, at most this far apart
#: (mm): about biv-me's contour points (3 mm) and the contour RBF's 4 mm offset, and few enough for a quick fit.
CONTOUR_SPACING = 5.0
#: a node attribute naming the label of a closed curve or point list (else its name without a copy number).
LABEL_ATTRIBUTE = "BiteMesh.Label"
#: a trailing copy number of a node name: "LV_ENDO_1", "LV_ENDO 2" and "LV_ENDO-3" are contours of LV_ENDO.
COPY_NUMBER = re.compile(r"[ _-]+\d+$")


def loadLabelledPoints(path, name=None, scene=None, coordinateSystem="LPS"):
    """A model node in ``scene`` holding the labelled contour points of a file, to mesh with
    :meth:`BiteMeshLogic.process`.

    Parameters
    ----------
    path : a biv-me GPFile (.txt), a CSV table or a VTK file (.vtp) with a ``Label`` point array, as read by
        bitemesh.io.read_labelled_points
    name : the node's name; default the file's name without its extension
    scene : vtkMRMLScene; default slicer.mrmlScene
    coordinateSystem : "LPS" (default) or "RAS", the frame of the file's coordinates (mm).  Files are LPS as
        Slicer reads its own model and markups files, and as DICOM's patient coordinates are, in which biv-me
        writes GPFiles (the points of bitemesh's sample GPFile lie on the slice planes that its SliceInfoFile's
        ImagePositionPatient and ImageOrientationPatient give); LPS points are turned to RAS, x and y negated, so
        that they overlay the images of the same study.

    Returns
    -------
    vtkMRMLModelNode: one vertex per point (world RAS, mm), point arrays ``Label`` (vtkStringArray) and, when the
    file gives slices, ``Slice`` (int64).
    """
    requireBitemesh()
    from bitemesh.convert import nodes_to_polydata
    from bitemesh.core.errors import check_choice
    from bitemesh.io import read_labelled_points

    check_choice(coordinateSystem, "coordinateSystem", COORDINATE_SYSTEMS)
    points, labels, slices = read_labelled_points(path)
    if coordinateSystem == "LPS":
        points = points * np.array([-1.0, -1.0, 1.0])
    polydata = nodes_to_polydata(points)
    labelArray = vtkStringArray()
    labelArray.SetName("Label")
    labelArray.SetNumberOfValues(len(labels))
    for index, label in enumerate(labels.tolist()):
        labelArray.SetValue(index, label)
    polydata.GetPointData().AddArray(labelArray)
    if slices is not None:
        sliceArray = numpy_support.numpy_to_vtk(np.ascontiguousarray(slices, dtype=np.int64), deep=True)
        sliceArray.SetName("Slice")
        polydata.GetPointData().AddArray(sliceArray)
    scene = slicer.mrmlScene if scene is None else scene
    node = scene.AddNewNodeByClass("vtkMRMLModelNode", name or Path(path).stem)
    node.SetAndObservePolyData(polydata)
    node.CreateDefaultDisplayNodes()
    node.GetDisplayNode().SetPointSize(LABELLED_POINT_SIZE)
    return node


def labelledPoints(nodes):
    """Labelled contour points of the input nodes, in world coordinates (mm).

    A model gives its points, its point array ``Label`` and its ``Slice`` (or ``FrameID``) array when present; a
    closed curve (one slice of its own) its curve resampled evenly by arc length (at least its control points,
    at most :data:`CONTOUR_SPACING` apart) and a point list its placed points (slice unknown), each labelled
    :func:`contourLabel`.

    Returns
    -------
    points : (n, 3) float64; labels : (n,) str
    slices : (n,) int64 slice ids (-1: unknown), or None when no point has one (bitemesh then finds the slice
        planes)
    """
    from bitemesh.convert import point_coordinates
    from bitemesh.core.errors import InvalidInputError
    parts, nextSlice = [], 0
    for node in nodes:
        if node.IsA("vtkMRMLModelNode"):
            labels, slices = modelLabels(node)
            if labels is None:
                raise InvalidInputError(
                    f"inputNode: the model '{node.GetName()}' has no point array Label, and labelled contours "
                    "need a label per point; load them with loadLabelledPoints, or clear domain and mesh the "
                    "model alone as a surface")
            points = point_coordinates(worldPolyData(node))
            labels = (labels.astype(np.int64) if labels.dtype.kind in "iuf" else labels).astype(str)
            if slices is None:
                slices = np.full(len(points), -1, dtype=np.int64)
            else:   # the model's own ids, moved past those already taken
                slices = np.where(slices >= 0, slices + nextSlice, -1)
        else:
            if node.IsA("vtkMRMLMarkupsClosedCurveNode"):
                curve = closedCurvePoints(node)
                count = max(node.GetNumberOfControlPoints(), math.ceil(closedLength(curve) / CONTOUR_SPACING))
                points, number = resampleClosed(curve, count), nextSlice
            else:
                points, number = pointListPoints(node), -1
            labels = np.full(len(points), contourLabel(node))
            slices = np.full(len(points), number, dtype=np.int64)
        nextSlice = max(nextSlice, int(slices.max()) + 1)
        parts.append((points, labels, slices))
    slices = np.concatenate([part[2] for part in parts])
    return (np.vstack([part[0] for part in parts]), np.concatenate([part[1] for part in parts]),
            slices if (slices >= 0).any() else None)


def modelLabels(node):
    """(labels (n,) or None, slices (n,) int64 or None) of a model: its point arrays ``Label`` and ``Slice`` or
    ``FrameID`` (bitemesh.convert.point_labels)."""
    from bitemesh.convert import point_labels
    polydata = node.GetPolyData()
    if polydata is None:
        return None, None
    return point_labels(polydata, f"inputNode: the model '{node.GetName()}'")


def hasLabelledModel(nodes) -> bool:
    """Whether any of ``nodes`` is a model with a ``Label`` point array (labelled contour points)."""
    return any(node.IsA("vtkMRMLModelNode") and modelLabels(node)[0] is not None for node in nodes)


def contourLabel(node) -> str:
    """The label of a closed curve or point list: its attribute :data:`LABEL_ATTRIBUTE`, else its name without a
    trailing copy number ("LV_ENDO_2" -> "LV_ENDO")."""
    from bitemesh.core.errors import InvalidInputError
    label = (node.GetAttribute(LABEL_ATTRIBUTE) or "").strip()
    if not label:
        name = (node.GetName() or "").strip()
        label = COPY_NUMBER.sub("", name) or name
    if not label:
        raise InvalidInputError(f"inputNode: the {node.GetClassName()} '{node.GetID()}' has no name; name it after "
                                f"its surface (e.g. LV_ENDO) or set its attribute {LABEL_ATTRIBUTE}")
    return label

