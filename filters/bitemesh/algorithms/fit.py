"""TemplateFit: the elastic template (a tagged mesh) moved onto new data with the same cells, as a VTK filter."""
from __future__ import annotations

from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkPolyData, vtkUnstructuredGrid
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from ..convert import mesh_to_unstructured, tags_to_polydata, with_polydata_tags
from ..core.fem.template import FitParameters
from ..fitting import fit
from .base import BitemeshAlgorithm, with_parameters
from .fibres import tetrahedra


@with_parameters(FitParameters)
class TemplateFit(BitemeshAlgorithm):
    """A template (port 0: a tetrahedral vtkUnstructuredGrid; port 1: its tagged boundary, the meshing filters'
    second output) and the data (port 2: labelled contours, a vtkPolyData with a ``Label`` point array; scattered
    points; or a label map as vtkImageData) -> the template moved onto the data with the same cells
    (:func:`bitemesh.fit`): port 0 the mesh (its cell arrays kept, Fibre / Sheet / SheetNormal carried by the
    deformation, the quality arrays of the moved cells), port 1 its tagged boundary, so that the next frame's
    TemplateFit chains on.  ``Pull``: the data's pull relative to the template's stiffness."""

    def __init__(self):
        super().__init__(nInputPorts=3, inputType="vtkDataObject", nOutputPorts=2, outputType="vtkUnstructuredGrid")

    def FillInputPortInformation(self, port, info):
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(),
                 ("vtkUnstructuredGrid", "vtkPolyData", "vtkDataSet")[port])
        return 1

    def FillOutputPortInformation(self, port, info):
        info.Set(vtkDataObject.DATA_TYPE_NAME(), "vtkUnstructuredGrid" if port == 0 else "vtkPolyData")
        return 1

    def execute(self, request, inInfo, outInfo):
        template = with_polydata_tags(tetrahedra(vtkUnstructuredGrid.GetData(inInfo[0])),
                                      vtkPolyData.GetData(inInfo[1]))
        fitted = fit(template, vtkDataObject.GetData(inInfo[2]), pull=self.parameters(FitParameters).pull,
                     progress=self.progress)
        mesh_to_unstructured(fitted.mesh, vtkUnstructuredGrid.GetData(outInfo, 0))
        tags_to_polydata(fitted.mesh, vtkPolyData.GetData(outInfo, 1))
