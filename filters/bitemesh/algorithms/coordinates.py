"""VentricularCoordinates: a biventricular mesh's ventricular coordinates and AHA segments as a VTK filter."""
from __future__ import annotations

from vtkmodules.vtkCommonDataModel import vtkUnstructuredGrid

from ..core.fem.coordinates import ventricular_coordinates
from .fibres import HeartArrays, vtk_array


class VentricularCoordinates(HeartArrays):
    """A biventricular tetrahedral mesh (port 0, vtkUnstructuredGrid) and its tagged boundary (port 1, vtkPolyData:
    the meshing filters' second output, with EPI, LV_ENDO, RV_ENDO and BASE among its names) -> the mesh with its
    ventricular coordinates (:mod:`bitemesh.core.fem.coordinates`).

    The output is the input mesh, every array kept, plus the point scalars ``ApicoBasal``, ``Transmural``,
    ``Rotational`` (radians), ``Transventricular`` and the Laplace solutions ``Psi``, ``PhiEpi``, ``PhiLV``,
    ``PhiRV``, and the cell scalars ``AHA`` (the 17 segments, 0 in the RV free wall) and ``Ventricle`` (1 LV free
    wall, 2 RV free wall, 3 septum).
    """

    def execute(self, request, inInfo, outInfo):
        source, mesh = self.heart(inInfo)
        found = ventricular_coordinates(mesh)
        output = vtkUnstructuredGrid.GetData(outInfo)
        output.ShallowCopy(source)
        for name, values in found.points.items():
            output.GetPointData().AddArray(vtk_array(name, values))
        output.GetCellData().AddArray(vtk_array("AHA", found.aha))
        output.GetCellData().AddArray(vtk_array("Ventricle", found.ventricle))
        output.GetCellData().SetActiveScalars("AHA")
