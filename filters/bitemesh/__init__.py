"""bitemesh: tetrahedral meshes from scattered points, contours and label maps, after Schaerer et al. ("biting").

    result = bitemesh.mesh("GPFile_000.txt")                 # any input, every option by name: cells=20000, ...
    bitemesh.write(result, "heart.vtu")                      # the mesh, its tags and companions, atomically
    mesh = bitemesh.read("heart.vtu")

:func:`mesh` is the front door (:mod:`bitemesh.meshing`); :class:`Options` holds every option; the VTK filters
(``PointsToImplicit`` ... ``MeshFromPoints``) chain in VTK and ParaView; :func:`batch` meshes a cohort on Dask;
:mod:`bitemesh.core` holds the steps for those who compose them.  Every name loads on first use, so that
``import bitemesh`` (and the ``bitemesh`` command's start, which Ctrl-C may interrupt) costs nothing.
"""
__version__ = "0.1.0"
FILTERS = ("PointsToImplicit", "BitingSampler", "DelaunayTetra", "SpuriousCellFilter", "MeshOptimizer",
           "QualityFilter", "MeshFromPoints", "FibreField", "TemplateFit", "VentricularCoordinates")
#: name -> (the module that defines it, its name there).
_NAMES = {"mesh": ("meshing", "mesh"), "write": ("meshing", "write"), "read": ("io.mesh_reading", "read_mesh"),
          "fit": ("fitting", "fit"), "fit_cycle": ("fitting", "fit_cycle"), "carry": ("core.fem.coordinates", "carry"),
          "Samples": ("meshing", "Samples"), "Voxels": ("meshing", "Voxels"), "Options": ("options", "Options"),
          "MeshingResult": ("core.steps.spine", "MeshingResult"), "Mesh": ("core.mesh.simplicial", "Mesh"),
          "batch": ("cohorts", "batch"),
          **{name: ("core.errors", name) for name in ("BitemeshError", "BitemeshWarning", "Cancelled",
                                                       "InvalidInputError", "MeshingError")},
          **{name: ("algorithms", name) for name in FILTERS}}
__all__ = sorted(_NAMES)


def __getattr__(name):
    """``bitemesh.mesh``, ``from bitemesh import PointsToImplicit``: the module is imported when first asked for."""
    if name in _NAMES:
        from importlib import import_module
        module, attribute = _NAMES[name]
        return getattr(import_module(f".{module}", __name__), attribute)
    raise AttributeError(f"module 'bitemesh' has no attribute {name!r}")
