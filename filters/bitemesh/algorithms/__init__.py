"""The bitemesh VTK filters (VTKPythonAlgorithmBase subclasses); they import only ``vtkmodules``."""
from .coordinates import VentricularCoordinates
from .fibres import FibreField
from .fit import TemplateFit
from .filters import (BitingSampler, DelaunayTetra, MeshFromPoints, MeshOptimizer, PointsToImplicit,
                      QualityFilter, SpuriousCellFilter)

__all__ = ["BitingSampler", "DelaunayTetra", "FibreField", "MeshFromPoints", "MeshOptimizer", "PointsToImplicit",
           "QualityFilter", "SpuriousCellFilter", "TemplateFit", "VentricularCoordinates"]
