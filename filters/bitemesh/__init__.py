"""bitemesh: tetrahedral meshes from scattered points, after Schaerer et al. ("biting" node placement).

The core (``bitemesh.core``) needs only numpy and scipy; file I/O and the VTK filters load VTK when used.
"""
from .core.errors import BitemeshError, Cancelled, InvalidInputError, MeshingError
from .core.mesh import Mesh
from .core.pipeline import mesh_from_points, run
from .core.quality import quality_summary

__version__ = "0.1.0"
__all__ = ["BitemeshError", "Cancelled", "InvalidInputError", "Mesh", "MeshingError", "mesh_from_points",
           "quality_summary", "run"]
