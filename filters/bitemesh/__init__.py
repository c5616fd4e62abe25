"""bitemesh: tetrahedral meshes from scattered points, after Schaerer et al. ("biting" node placement).

The core (``bitemesh.core``) needs only numpy and scipy; file I/O and the VTK filters load VTK when used.  Every
name below loads on first use, so that ``import bitemesh`` (and the ``bitemesh`` command's start, which Ctrl-C may
interrupt) costs nothing.
"""
__version__ = "0.1.0"
FILTERS = ("PointsToImplicit", "BitingSampler", "DelaunayTetra", "SpuriousCellFilter", "MeshOptimizer",
           "QualityFilter", "MeshFromPoints", "FibreField")
#: name -> the module that defines it.
_CORE = {"BitemeshError": "core.errors", "BitemeshWarning": "core.errors", "Cancelled": "core.errors",
         "InvalidInputError": "core.errors", "MeshingError": "core.errors", "Mesh": "core.mesh.simplicial",
         "mesh_from_points": "core.sources.points", "run": "core.sources.points",
         "quality_summary": "core.mesh.quality",
         "batch": "cohorts",
         **{name: "algorithms" for name in FILTERS}}
__all__ = sorted(_CORE)


def __getattr__(name):
    """``bitemesh.run``, ``from bitemesh import PointsToImplicit``: the module is imported when first asked for."""
    if name in _CORE:
        from importlib import import_module
        return getattr(import_module(f".{_CORE[name]}", __name__), name)
    raise AttributeError(f"module 'bitemesh' has no attribute {name!r}")
