"""A segment of a segmentation node: its binary labelmap, meshed in its voxel frame and carried to world with its
tags (the segment is one region, its boundary BOUNDARY_1)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import slicer
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonMath import vtkMatrix4x4

from .points import toWorld, transformPoints


def segmentLabelmap(node, segmentId=None):
    """One segment of a segmentation node as a binary label array and its geometry.

    Returns
    -------
    labels : (n_i, n_j, n_k) uint8, 1 inside, indexed [i, j, k] from the extent's first voxel
    spacing : (3,) voxel size (mm); ijk0 : (3,) IJK index of labels[0, 0, 0]
    ijkToWorld : (4, 4) IJK -> RAS of the segmentation's frame (the node's parent transforms not included)
    """
    from bitemesh.core.errors import InvalidInputError
    segmentation = node.GetSegmentation()
    ids = [segmentation.GetNthSegmentID(i) for i in range(segmentation.GetNumberOfSegments())]
    if not ids:
        raise InvalidInputError(f"inputNode: the segmentation '{node.GetName()}' has no segments")
    segmentId = ids[0] if segmentId in (None, "") else segmentId
    if segmentId not in ids:
        names = ", ".join(f"{i} ({segmentation.GetSegment(i).GetName()})" for i in ids)
        raise InvalidInputError(f"segmentId: '{segmentId}' is not a segment of '{node.GetName()}'; segments: {names}")
    name = slicer.vtkSegmentationConverter.GetSegmentationBinaryLabelmapRepresentationName()
    if not segmentation.ContainsRepresentation(name):
        node.CreateBinaryLabelmapRepresentation()
        if not segmentation.ContainsRepresentation(name):
            raise InvalidInputError(f"inputNode: the segmentation '{node.GetName()}' could not be converted to a "
                                    "binary labelmap; create one in the Segmentations module")
    image = slicer.vtkOrientedImageData()
    node.GetBinaryLabelmapRepresentation(segmentId, image)
    segmentName = segmentation.GetSegment(segmentId).GetName()
    scalars = image.GetPointData().GetScalars() if image.GetNumberOfPoints() else None
    if scalars is None:
        raise InvalidInputError(f"inputNode: the segment '{segmentName}' is empty; paint it first")
    dims = image.GetDimensions()
    labels = (numpy_support.vtk_to_numpy(scalars).reshape(dims, order="F") != 0).astype(np.uint8)
    if not labels.any():
        raise InvalidInputError(f"inputNode: the segment '{segmentName}' is empty; paint it first")
    matrix = vtkMatrix4x4()
    image.GetImageToWorldMatrix(matrix)
    ijkToWorld = np.array([[matrix.GetElement(r, c) for c in range(4)] for r in range(4)])
    extent = image.GetExtent()
    return labels, np.array(image.GetSpacing(), dtype=np.float64), np.array(extent[::2], dtype=np.float64), \
        ijkToWorld


def meshSegment(node, segmentId, options, progress):
    """Mesh one segment: its binary labelmap as bitemesh.Voxels through bitemesh.mesh (the path the bitemesh
    command takes for label map files), which meshes in the voxel frame and places the mesh with the labelmap's
    IJK-to-RAS matrix; then the segmentation's parent transforms carry it to world."""
    import bitemesh
    from bitemesh.core.mesh.quality import cell_quality
    from bitemesh.core.mesh.simplicial import signed_measures

    labels, _, ijk0, ijkToWorld = segmentLabelmap(node, segmentId)
    firstVoxel = np.eye(4)
    firstVoxel[:3, 3] = ijk0   # labels[0, 0, 0] is voxel ijk0 of the labelmap's frame
    result = bitemesh.mesh(bitemesh.Voxels(labels, ijkToWorld @ firstVoxel), options, progress=progress)
    transform = toWorld(node)
    if transform is None:
        return result.mesh, result
    mesh = result.mesh
    points = transformPoints(transform, mesh.points)
    cells, facets = mesh.cells, mesh.facets
    if np.sum(signed_measures(points, cells)) < 0:   # a parent transform that reflects: cells and facets turn back
        cells, facets = cells[:, [0, 2, 1, 3]], facets[:, [0, 2, 1]]
    moved = replace(mesh, points=points, cells=cells, facets=facets)
    return moved.with_cell_data(**cell_quality(moved)), result

