"""bitemesh: tetrahedral meshes from scattered points, after Schaerer et al. ("biting" node placement).

The core (``bitemesh.core``) needs only numpy and scipy; file I/O and the VTK filters load VTK when used.
"""
from .core.errors import BitemeshError, Cancelled, InvalidInputError, MeshingError
from .core.mesh import Mesh
from .core.pipeline import mesh_from_points, run
from .core.quality import quality_summary

__version__ = "0.1.0"
FILTERS = ("PointsToImplicit", "BitingSampler", "DelaunayTetra", "SpuriousCellFilter", "MeshOptimizer",
           "QualityFilter", "MeshFromPoints")
__all__ = ["BitemeshError", "Cancelled", "InvalidInputError", "Mesh", "MeshingError", "mesh_from_points",
           "quality_summary", "run", *FILTERS]


def __getattr__(name):
    """The VTK filters load VTK only when first asked for: ``from bitemesh import PointsToImplicit``."""
    if name in FILTERS:
        from . import algorithms
        return getattr(algorithms, name)
    raise AttributeError(f"module 'bitemesh' has no attribute {name!r}")
