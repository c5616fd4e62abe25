"""FibreField: the rule-based myocardial fibres of a biventricular mesh (Bayer et al. 2012) as a VTK filter."""
from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import VTK_TRIANGLE, vtkPolyData, vtkUnstructuredGrid
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from ..convert import point_coordinates, unstructured_to_mesh
from ..core.errors import InvalidInputError
from ..core.fibres import FIBRE_ARRAYS, LAPLACE_ARRAYS, FibreParameters, fibre_field
from ..core.mesh import Mesh
from .base import BitemeshAlgorithm, with_parameters

#: the tagged facets' arrays (the meshing filters' second output): the cell array of the tags, and the field data
#: of the names, parallel to their tags and dimensions (2 for a facet tag, 3 for a region).
SURFACE_TAG, TAG_FIELDS = "SurfaceTag", ("TagNames", "TagValues", "TagDimensions")


def tagged_boundary(facets: vtkPolyData, points: np.ndarray):
    """The tagged triangles of a vtkPolyData that shares the mesh's points (point ids = node ids).

    Parameters
    ----------
    facets : triangles, cell array ``SurfaceTag``, field data ``TagNames`` (vtkStringArray), ``TagValues`` and
        ``TagDimensions`` (vtkIntArray), one entry a name
    points : (n, 3) float64, the mesh's nodes, which ``facets`` must hold in the same order

    Returns
    -------
    triangles : (b, 3) int64; tags : (b,) int32; names : name -> (tag, dimension)
    """
    hint = "connect the tagged facets of this mesh (a meshing filter's second output) to port 1"
    count = 0 if facets is None else facets.GetNumberOfPoints()
    if count != len(points):
        raise InvalidInputError(f"port 1: the tagged facets hold {count} points and the mesh {len(points)}; they "
                                "must share the mesh's points (point ids = node ids); " + hint)
    if not np.allclose(point_coordinates(facets), points, rtol=0, atol=1e-9 * np.ptp(points, axis=0).max()):
        raise InvalidInputError("port 1: the tagged facets' points are not the mesh's (point ids = node ids); "
                                + hint)
    tags = facets.GetCellData().GetArray(SURFACE_TAG)
    fields = [facets.GetFieldData().GetAbstractArray(name) for name in TAG_FIELDS]
    missing = [name for name, array in zip((SURFACE_TAG, *TAG_FIELDS), (tags, *fields)) if array is None]
    if missing:
        raise InvalidInputError(f"port 1: the tagged facets have no {', '.join(missing)} (a cell array "
                                f"{SURFACE_TAG} and the field data {', '.join(TAG_FIELDS)}); " + hint)
    polys = facets.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    if facets.GetNumberOfCells() != len(offsets) - 1 or np.any(np.diff(offsets) != 3):
        raise InvalidInputError(f"port 1: the tagged facets must be triangles (VTK_TRIANGLE = {VTK_TRIANGLE}) and "
                                "nothing else; " + hint)
    triangles = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64).reshape(-1, 3)
    names, values, dimensions = fields
    named = {names.GetValue(i): (values.GetValue(i), dimensions.GetValue(i)) for i in range(names.GetNumberOfValues())}
    return triangles, numpy_support.vtk_to_numpy(tags).astype(np.int32), named


def vtk_array(name: str, values: np.ndarray):
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    array.SetName(name)
    return array


@with_parameters((FibreParameters, ("alpha_endo", "alpha_epi", "beta_endo", "beta_epi")))
class FibreField(BitemeshAlgorithm):
    """A biventricular tetrahedral mesh (port 0, vtkUnstructuredGrid) and its tagged boundary (port 1, vtkPolyData:
    the meshing filters' second output, with EPI, LV_ENDO, RV_ENDO and BASE among its names) -> the mesh with the
    rule-based fibres of Bayer et al. (2012, :mod:`bitemesh.core.fibres`).

    The output is the input mesh, every array kept, plus the cell vectors ``Fibre``, ``Sheet`` and ``SheetNormal``
    (unit, orthogonal), the cell scalar ``HelixAngle`` (degrees, for colouring) and the point scalars of the four
    Laplace solutions (``Psi``, ``PhiEpi``, ``PhiLV``, ``PhiRV``).  ``AlphaEndo``,
    ``AlphaEpi``, ``BetaEndo``, ``BetaEpi``: the angles, in degrees (defaults: the paper's).
    """

    def __init__(self):
        super().__init__(nInputPorts=2, inputType="vtkDataObject", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def FillInputPortInformation(self, port, info):
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkUnstructuredGrid" if port == 0 else "vtkPolyData")
        return 1

    def execute(self, request, inInfo, outInfo):
        source = vtkUnstructuredGrid.GetData(inInfo[0])
        mesh = unstructured_to_mesh(source)
        if mesh.dim != 3 or len(mesh.cells) != source.GetNumberOfCells():
            raise InvalidInputError(f"the mesh must hold tetrahedra only; {source.GetNumberOfCells() - len(mesh.cells)}"
                                    f" of its {source.GetNumberOfCells()} cells are not")
        triangles, tags, names = tagged_boundary(vtkPolyData.GetData(inInfo[1]), mesh.points)
        field = fibre_field(Mesh(mesh.points, mesh.cells, {}, triangles, tags, names),
                            self.parameters(FibreParameters), self.progress)
        output = vtkUnstructuredGrid.GetData(outInfo)
        output.ShallowCopy(source)
        for name, values in zip(FIBRE_ARRAYS, (field.fibre, field.sheet, field.sheet_normal, field.helix_angle)):
            output.GetCellData().AddArray(vtk_array(name, values))
        output.GetCellData().SetActiveVectors("Fibre")
        for name in LAPLACE_ARRAYS:
            output.GetPointData().AddArray(vtk_array(name, field.laplace[name]))
