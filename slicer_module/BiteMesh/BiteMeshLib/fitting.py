"""The elastic template in Slicer: a BiteMesh output (its model node and the surface models it references) as the
template, and the nodes its data come from, for :meth:`BiteMeshLogic.fitTemplate`."""
from __future__ import annotations

import numpy as np

from .contours import hasLabelledModel, labelledPoints
from .outputs import SURFACE_ROLE
from .points import scatteredPoints


def templateMesh(templateNode):
    """The tetrahedral bitemesh Mesh of a BiteMesh output model node, tagged by the surface models it references
    (they share its points; world RAS, mm)."""
    from bitemesh.convert import polydata_to_tags, unstructured_to_mesh
    from bitemesh.core.errors import InvalidInputError

    grid = templateNode.GetMesh() if templateNode is not None and templateNode.IsA("vtkMRMLModelNode") else None
    if grid is None or not grid.IsA("vtkUnstructuredGrid") or grid.GetNumberOfCells() == 0:
        raise InvalidInputError("templateNode: a model node holding a BiteMesh tetrahedral mesh is needed (the output "
                                "of Apply, with its surface models)")
    mesh = unstructured_to_mesh(grid)
    facets, tags, names = [], [], {}
    for index in range(templateNode.GetNumberOfNodeReferences(SURFACE_ROLE)):
        surface = templateNode.GetNthNodeReference(SURFACE_ROLE, index)
        if surface is not None and surface.GetPolyData() is not None:
            found = polydata_to_tags(surface.GetPolyData(), mesh)
            facets.append(found[0])
            tags.append(found[1])
            names.update(found[2])
    if not facets:
        raise InvalidInputError(f"templateNode: {templateNode.GetName()} references no surface models (EPI, LV_ENDO, "
                                "...): mesh the template with BiteMesh, which makes them")
    return mesh.with_tags(np.concatenate(facets), np.concatenate(tags), names)


def fitSamples(nodes):
    """bitemesh.Samples of the data nodes: labelled (a model with a ``Label`` array) or scattered points."""
    import bitemesh

    if hasLabelledModel(nodes):
        points, labels, slices = labelledPoints(nodes)
        return bitemesh.Samples(points, labels=labels, slices=slices)
    points, _, slices = scatteredPoints(nodes, "mpu")
    return bitemesh.Samples(points, slices=slices)
