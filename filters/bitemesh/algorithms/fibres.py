"""FibreField: the rule-based myocardial fibres of a biventricular mesh (Bayer et al. 2012) as a VTK filter."""
from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData, vtkUnstructuredGrid
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from ..convert import unstructured_to_mesh, with_polydata_tags
from ..core.errors import InvalidInputError
from ..core.fem.fibres import FIBRE_ARRAYS, LAPLACE_ARRAYS, FibreParameters, fibre_field
from .base import BitemeshAlgorithm, with_parameters


def tetrahedra(grid: vtkUnstructuredGrid):
    """The bitemesh Mesh of a vtkUnstructuredGrid that holds tetrahedra only; else InvalidInputError saying how many
    cells are not."""
    mesh = unstructured_to_mesh(grid)
    if mesh.dim != 3 or len(mesh.cells) != grid.GetNumberOfCells():
        raise InvalidInputError(f"the mesh must hold tetrahedra only; {grid.GetNumberOfCells() - len(mesh.cells)}"
                                f" of its {grid.GetNumberOfCells()} cells are not")
    return mesh


def vtk_array(name: str, values: np.ndarray):
    """A named VTK array of ``values`` (m,) or (m, c), copied."""
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    array.SetName(name)
    return array


class HeartArrays(BitemeshAlgorithm):
    """Base of the filters that add arrays to a heart's tetrahedral mesh (port 0, vtkUnstructuredGrid) from it and
    its tagged boundary (port 1, vtkPolyData: the meshing filters' second output); one output, the mesh."""

    def __init__(self):
        super().__init__(nInputPorts=2, inputType="vtkDataObject", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def FillInputPortInformation(self, port, info):
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkUnstructuredGrid" if port == 0 else "vtkPolyData")
        return 1

    @staticmethod
    def heart(inInfo):
        """(the input grid, its tagged Mesh) of the two input ports."""
        source = vtkUnstructuredGrid.GetData(inInfo[0])
        return source, with_polydata_tags(tetrahedra(source), vtkPolyData.GetData(inInfo[1]))


@with_parameters((FibreParameters, ("alpha_endo", "alpha_epi", "beta_endo", "beta_epi")))
class FibreField(HeartArrays):
    """A biventricular tetrahedral mesh (port 0, vtkUnstructuredGrid) and its tagged boundary (port 1, vtkPolyData:
    the meshing filters' second output, :func:`bitemesh.convert.tags_to_polydata`, with EPI, LV_ENDO, RV_ENDO and
    BASE among its names) -> the mesh with the rule-based fibres of Bayer et al. (2012,
    :mod:`bitemesh.core.fem.fibres`).

    The output is the input mesh, every array kept, plus the cell vectors ``Fibre``, ``Sheet`` and ``SheetNormal``
    (unit, orthogonal), the cell scalar ``HelixAngle`` (degrees, for colouring) and the point scalars of the four
    Laplace solutions (``Psi``, ``PhiEpi``, ``PhiLV``, ``PhiRV``).  ``AlphaEndo``, ``AlphaEpi``, ``BetaEndo``,
    ``BetaEpi``: the angles, in degrees (defaults: the paper's).
    """

    def execute(self, request, inInfo, outInfo):
        source, mesh = self.heart(inInfo)
        field = fibre_field(mesh, self.parameters(FibreParameters), self.progress)
        output = vtkUnstructuredGrid.GetData(outInfo)
        output.ShallowCopy(source)
        for name, values in zip(FIBRE_ARRAYS, (field.fibre, field.sheet, field.sheet_normal, field.helix_angle)):
            output.GetCellData().AddArray(vtk_array(name, values))
        output.GetCellData().SetActiveVectors("Fibre")
        for name in LAPLACE_ARRAYS:
            output.GetPointData().AddArray(vtk_array(name, field.laplace[name]))
