"""Distances between meshes, for test_pvbatch.py and for pvbatch_script.py inside pvbatch (no ParaView import)."""
from __future__ import annotations

import numpy as np
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.steps.fidelity import distances_to_facets


def boundary_hausdorff(first, second) -> float:
    """The symmetric Hausdorff distance between two meshes' boundary surfaces, taken at their boundary nodes: the
    largest distance from a boundary node of either mesh to the other's boundary triangles (exact:
    :func:`bitemesh.core.steps.fidelity.distances_to_facets`)."""
    return max(float(distances_to_facets(mesh.points[np.unique(boundary_facets(mesh.cells))],
                                         other.points[boundary_facets(other.cells)]).max())
               for mesh, other in ((first, second), (second, first)))
