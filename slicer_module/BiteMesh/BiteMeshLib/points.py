"""Points in world (RAS) coordinates from markups point lists, closed curves and surface models."""
from __future__ import annotations

import numpy as np
import slicer
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonTransforms import vtkGeneralTransform
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
from vtkmodules.vtkFiltersGeneral import vtkTransformPolyDataFilter

from . import requirements  # noqa: F401  (puts bitemesh on the path)

#: closed curves for the RBF are resampled to about this many points in all, at least MIN_CURVE_POINTS each.
RBF_CURVE_POINTS, MIN_CURVE_POINTS = 300, 16


def scatteredPoints(nodes, method: str):
    """(points (n, 3), normals (n, 3) or None, slices (n,) or None) in world coordinates from point lists,
    closed curves, models.

    Normals are kept only when every input gives them (closed curves and models with polygons do); slices (the
    curve of each point) only when every input is a closed curve.
    """
    from bitemesh.core.implicit.rbf import MAX_RBF_POINTS
    parts = []
    for node in nodes:
        if node.IsA("vtkMRMLMarkupsFiducialNode"):
            parts.append((pointListPoints(node), None))
        elif node.IsA("vtkMRMLMarkupsClosedCurveNode"):
            points = closedCurvePoints(node)
            parts.append((points, contourNormals(points, node.GetName())))
        else:
            parts.append(modelPoints(node))
    curves = [index for index, node in enumerate(nodes) if node.IsA("vtkMRMLMarkupsClosedCurveNode")]
    if method == "rbf" and curves:
        # The RBF costs (3 x points) per evaluation on every grid node: resample the densely interpolated curves
        # evenly by arc length to at most RBF_CURVE_POINTS in all, shared by length.
        others = sum(len(parts[i][0]) for i in range(len(parts)) if i not in curves)
        budget = max(min(RBF_CURVE_POINTS, MAX_RBF_POINTS - others), MIN_CURVE_POINTS * len(curves))
        lengths = np.array([closedLength(parts[i][0]) for i in curves])
        for index, length in zip(curves, lengths):
            count = max(MIN_CURVE_POINTS, round(budget * length / lengths.sum()))
            if count < len(parts[index][0]):
                points = resampleClosed(parts[index][0], count)
                parts[index] = (points, contourNormals(points, nodes[index].GetName()))
    points = np.vstack([part[0] for part in parts])
    normals = np.vstack([part[1] for part in parts]) if all(part[1] is not None for part in parts) else None
    slices = np.concatenate([np.full(len(part[0]), index) for index, part in enumerate(parts)]) \
        if len(curves) == len(nodes) else None
    return points, normals, slices


def pointListPoints(node) -> np.ndarray:
    """(n, 3) world positions of the defined control points of a markups point list."""
    from bitemesh.core.errors import InvalidInputError
    count = node.GetNumberOfControlPoints()
    defined = [i for i in range(count) if not hasattr(node, "GetNthControlPointPositionStatus")
               or node.GetNthControlPointPositionStatus(i) == node.PositionDefined]
    if not defined:
        raise InvalidInputError(f"inputNode: the point list '{node.GetName()}' has no placed control points; "
                                "place points on the surface to mesh (at least 10, typically hundreds)")
    points = np.zeros((len(defined), 3))
    position = [0.0, 0.0, 0.0]
    for row, index in enumerate(defined):
        node.GetNthControlPointPositionWorld(index, position)
        points[row] = position
    return points


def closedCurvePoints(node) -> np.ndarray:
    """(n, 3) points along a closed curve, in world coordinates: the curve as interpolated by Slicer (its curve
    points), without the point that repeats the first."""
    from bitemesh.core.errors import InvalidInputError
    curve = node.GetCurvePointsWorld() if node.GetNumberOfControlPoints() >= 3 else None
    if curve is None or curve.GetNumberOfPoints() < 3:
        raise InvalidInputError(f"inputNode: the closed curve '{node.GetName()}' has "
                                f"{node.GetNumberOfControlPoints()} control points; a contour needs at least 3")
    points = numpy_support.vtk_to_numpy(curve.GetData()).astype(np.float64).reshape(-1, 3)
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    step = np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1)
    points = points[step > 1e-9 * max(length, 1e-300)]   # drop repeats (the closing point repeats the first)
    if len(points) < 3 or length <= 0:
        raise InvalidInputError(f"inputNode: the closed curve '{node.GetName()}' is degenerate (zero length)")
    return points


def worldPolyData(node):
    """The polydata of a model through its parent transforms (world coordinates), with its point arrays."""
    from bitemesh.core.errors import InvalidInputError
    polydata = node.GetPolyData()
    if polydata is None or polydata.GetNumberOfPoints() == 0:
        what = "a volume mesh" if node.GetMesh() is not None and node.GetMesh().GetNumberOfPoints() else "no points"
        raise InvalidInputError(f"inputNode: the model '{node.GetName()}' holds {what}; give a surface model "
                                "(or points sampled on the surface)")
    transform = toWorld(node)
    if transform is None:
        return polydata
    moved = vtkTransformPolyDataFilter()
    moved.SetTransform(transform)
    moved.SetInputData(polydata)
    moved.Update()
    return moved.GetOutput()


def modelPoints(node):
    """(points, normals or None) of a surface model in world coordinates; normals from the model or computed
    from its polygons (auto-oriented outward); None when they are missing or unusable (bitemesh estimates them).
    """
    from bitemesh.convert import point_coordinates
    polydata = worldPolyData(node)
    points = point_coordinates(polydata)
    normals = polydata.GetPointData().GetNormals()
    if normals is None and polydata.GetNumberOfPolys() > 0:
        computed = vtkPolyDataNormals()
        computed.SetInputData(polydata)
        computed.ComputePointNormalsOn()
        computed.ComputeCellNormalsOff()
        computed.SplittingOff()
        computed.ConsistencyOn()
        computed.AutoOrientNormalsOn()
        computed.Update()
        if computed.GetOutput().GetNumberOfPoints() == len(points):
            normals = computed.GetOutput().GetPointData().GetNormals()
    if normals is None:
        return points, None
    normals = numpy_support.vtk_to_numpy(normals).astype(np.float64).reshape(-1, 3)
    usable = np.isfinite(normals).all() and (np.linalg.norm(normals, axis=1) > 0).all()
    return points, normals if usable else None


def contourNormals(points: np.ndarray, name: str = "curve") -> np.ndarray:
    """(n, 3) outward unit normals of a closed planar-ish curve, in its best-fit plane.

    The plane normal is the direction of least spread; each normal is (tangent x plane normal), the whole set
    flipped so that it points away from the enclosed area (positive flux through the curve).
    """
    from bitemesh.core.errors import InvalidInputError
    centred = points - points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    if spread[1] <= 1e-9 * spread[0]:
        raise InvalidInputError(f"inputNode: the closed curve '{name}' is a line; a contour must enclose an area")
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    normals = np.cross(tangent, axes[2])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    if not (length > 0).all():
        raise InvalidInputError(f"inputNode: the closed curve '{name}' doubles back on itself")
    normals /= length
    if np.einsum("ij,ij->", normals, centred) < 0:
        normals = -normals
    return normals


def closedLength(points: np.ndarray) -> float:
    """Length of the closed polyline through ``points``."""
    return float(np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1).sum())


def resampleClosed(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` points evenly spaced by arc length along the closed polyline through ``points``."""
    closed = np.vstack([points, points[:1]])
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(at, arc, closed[:, axis]) for axis in range(3)])


def toWorld(node):
    """The node's parent transforms to world as a vtkGeneralTransform, or None when it has none."""
    parent = node.GetParentTransformNode() if hasattr(node, "GetParentTransformNode") else None
    if parent is None:
        return None
    transform = vtkGeneralTransform()
    slicer.vtkMRMLTransformNode.GetTransformBetweenNodes(parent, None, transform)
    return transform


def transformPoints(transform, points: np.ndarray) -> np.ndarray:
    """(n, 3) points through a VTK transform."""
    source, target = vtkPoints(), vtkPoints()
    source.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    transform.TransformPoints(source, target)
    return numpy_support.vtk_to_numpy(target.GetData()).astype(np.float64).reshape(-1, 3)

