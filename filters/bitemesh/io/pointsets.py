"""Points with their normals from files: text tables (:mod:`.tables`) and VTK-readable surfaces and meshes.

``.vtp``, ``.vtk`` (legacy, also version 5.1), ``.vtu``, ``.ply``, ``.obj``, ``.stl``: the points of any VTK
dataset, with the point normals it stores or, for a surface without them, normals computed from its polygons.  A
volume mesh (tetrahedra, hexahedra, ...) gives its boundary surface: its interior nodes are not samples of a
surface.  VTK readers report failures by printing; here they are silenced and every failure becomes an
:class:`InvalidInputError` that names the file.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError, check_points
from .files import existing_file, logger, meshio_warnings, unit_rows, vtk_silenced
from .tables import column_roles, read_table, table_points

TEXT_POINT_EXTENSIONS = (".xyz", ".xy", ".txt", ".csv")
VTK_POINT_EXTENSIONS = (".vtp", ".vtk", ".vtu", ".ply", ".obj", ".stl")
POINT_EXTENSIONS = TEXT_POINT_EXTENSIONS + VTK_POINT_EXTENSIONS


def read_points(path, columns: str | None = None, dimension: int | None = None):
    """Read scattered points and, where the file has or implies them, point normals.

    Parameters
    ----------
    path : str or Path
        ``.xyz``, ``.txt``, ``.csv``: a table, one point per row (see :mod:`bitemesh.io.tables` for the columns,
        headers and decimal commas it understands).  ``.vtp``, ``.vtk``, ``.vtu``, ``.ply``, ``.obj``, ``.stl``:
        the points of a VTK dataset (the boundary surface of a volume mesh).
    columns : comma-separated role of each column of a table (x, y, z, nx, ny, nz, skip), e.g. "x,y,z,skip,skip,skip";
        default: from the header, or from the column count
    dimension : int 2 to 5, or None: a table's first ``dimension`` columns are the point, the next ``dimension``
        (when there) its normal (:func:`~bitemesh.io.tables.column_roles`)

    Returns
    -------
    points : (n, k) float64, input units; k = ``dimension``, else 2 for a 2-column or 4-column text file, else 3
    normals : (n, k) float64 unit vectors (zero where undefined), or None when the file gives no normals and no
        polygons to compute them from.  Computed normals are consistent across each connected surface; they point
        outward for closed manifold surfaces and follow the polygon ordering of open ones.

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, no points, columns that cannot be told apart, a
        labelled file (a label column: read it with read_labelled_points), or a malformed row (the message names
        the file and the line).
    """
    path = existing_file(path, "points", POINT_EXTENSIONS)
    if path.suffix.lower() not in TEXT_POINT_EXTENSIONS:
        if columns or dimension:
            raise InvalidInputError(f"{'columns' if columns else 'dimension'} applies to text tables, not to "
                                    f"'{path}' (a VTK dataset's points have 3 coordinates)")
        return _read_vtk_points(path)
    table = read_table(path)
    roles = column_roles(table, columns, dimension=dimension)
    if "label" in roles:
        table.fail("it has a label column: these are labelled contours; read them with read_labelled_points (the "
                   "bitemesh command does so for a file whose header names a label column)")
    points, normals = table_points(table, roles)
    return check_points(points, f"points of '{path}'"), None if normals is None else unit_rows(normals)


def _vtk_reader(path: Path):
    """A VTK reader set up for ``path`` (not .ply), or an error naming what is wrong with the file."""
    suffix = path.suffix.lower()
    name = str(path)
    if suffix == ".vtp":
        from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
        reader = vtkXMLPolyDataReader()
    elif suffix == ".vtu":
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
        reader = vtkXMLUnstructuredGridReader()
    elif suffix == ".vtk":
        from vtkmodules.vtkIOLegacy import (
            vtkDataSetReader,
            vtkPolyDataReader,
            vtkStructuredGridReader,
            vtkUnstructuredGridReader,
        )
        # Probe the header, then use the concrete reader: vtkDataSetReader prints through vtkLogger, even with
        # warnings off, when the file is not a dataset.
        probe = vtkDataSetReader()
        probe.SetFileName(name)
        readers = {0: vtkPolyDataReader, 2: vtkStructuredGridReader, 4: vtkUnstructuredGridReader}
        kind = probe.ReadOutputType()  # VTK_POLY_DATA 0, VTK_STRUCTURED_GRID 2, VTK_UNSTRUCTURED_GRID 4
        if kind not in readers:
            raise InvalidInputError(
                f"cannot read points from '{path}': not a legacy VTK file of points (needs a '# vtk DataFile' "
                "header and a DATASET of POLYDATA, UNSTRUCTURED_GRID or STRUCTURED_GRID; images and rectilinear "
                "grids are not point sets)")
        reader = readers[kind]()
    elif suffix == ".obj":
        from vtkmodules.vtkIOGeometry import vtkOBJReader
        reader = vtkOBJReader()
    else:  # .stl
        from vtkmodules.vtkIOGeometry import vtkSTLReader
        reader = vtkSTLReader()
        reader.MergingOn()  # STL repeats every vertex in each facet
    reader.SetFileName(name)
    return reader


def _read_vtk_points(path: Path):
    from vtkmodules.util.numpy_support import vtk_to_numpy

    if path.suffix.lower() == ".ply":
        dataset = _read_ply(path)
    else:
        with vtk_silenced():
            reader = _vtk_reader(path)
            succeeded = reader.GetExecutive().Update()
            dataset = reader.GetOutputDataObject(0)
        if not succeeded or reader.GetErrorCode():
            from vtkmodules.vtkCommonMisc import vtkErrorCode
            reason = vtkErrorCode.GetStringFromErrorCode(reader.GetErrorCode()) if reader.GetErrorCode() else ""
            reason = "" if reason in ("NoError", "UnknownError") else reason
            raise InvalidInputError(
                f"cannot read points from '{path}': the {reader.GetClassName()} failed"
                + (f" ({reason})" if reason else "") + "; is the file truncated, or not of the format its "
                "extension says?")
    points = dataset.GetPoints() if dataset is not None and hasattr(dataset, "GetPoints") else None
    if points is None or points.GetNumberOfPoints() == 0:
        raise InvalidInputError(
            f"cannot read points from '{path}': the file holds no points (is it truncated, or not of the "
            "format its extension says?)")
    if _max_cell_dimension(dataset) == 3:
        dataset = _boundary_surface(dataset, path)
        points = dataset.GetPoints()
    coordinates = np.array(vtk_to_numpy(points.GetData()), dtype=np.float64).reshape(-1, 3)
    coordinates = check_points(coordinates, f"points of '{path}'", dims=(3,))
    normals = _point_normals(dataset)
    if normals is None:
        with vtk_silenced():
            normals = _normals_from_polygons(dataset)
        if normals is not None:
            # a surface's points that no polygon uses (duplicates, strays) have no normal: leave them out
            used = np.any(normals != 0, axis=1)
            coordinates, normals = coordinates[used], normals[used]
    if normals is not None:
        normals = unit_rows(np.where(np.isfinite(normals), normals, 0.0))
    return coordinates, normals


def _boundary_surface(dataset, path: Path):
    """The boundary surface (vtkPolyData, its own points only) of a volume mesh, without the mesh's point data:
    its interior nodes are not samples of a surface, and its normals are those of the boundary polygons."""
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter

    surface = vtkDataSetSurfaceFilter()
    surface.SetInputData(dataset)
    with vtk_silenced():
        surface.Update()
    boundary = surface.GetOutput()
    boundary.GetPointData().Initialize()
    if boundary.GetNumberOfPolys() == 0:
        raise InvalidInputError(f"cannot read points from '{path}': its volume cells have no boundary surface")
    logger.info("'%s' is a volume mesh (%d cells, %d points): its boundary surface (%d points) is meshed",
                path.name, dataset.GetNumberOfCells(), dataset.GetNumberOfPoints(), boundary.GetNumberOfPoints())
    return boundary


def _read_ply(path: Path):
    """The PLY file as a vtkPolyData (points, polygons, normals from ``nx ny nz``), parsed by meshio.

    Not vtkPLYReader: it crashes the interpreter (segmentation fault) on a truncated binary file.
    """
    import meshio
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    with meshio_warnings():
        try:
            data = meshio.ply.read(str(path))
        except Exception as error:  # noqa: BLE001  (ReadError, ValueError, KeyError, ... on bad files)
            raise InvalidInputError(
                f"cannot read points from '{path}': not a readable PLY file ({type(error).__name__}: {error})"
            ) from None
    coordinates = np.asarray(data.points, dtype=np.float64)
    if coordinates.ndim != 2 or coordinates.shape[1] != 3:
        raise InvalidInputError(f"cannot read points from '{path}': PLY vertices need x, y and z")
    surface = vtkPolyData()
    points = vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(coordinates), deep=True))
    surface.SetPoints(points)
    faces = [np.asarray(block.data, dtype=np.int64) for block in data.cells if np.ndim(block.data) == 2]
    faces = [block for block in faces if block.shape[1] >= 3]
    if faces:
        if any(block.min() < 0 or block.max() >= len(coordinates) for block in faces):
            raise InvalidInputError(f"cannot read points from '{path}': a PLY face indexes a missing vertex")
        sizes = np.concatenate([np.full(len(block), block.shape[1], dtype=np.int64) for block in faces])
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        connectivity = np.concatenate([block.ravel() for block in faces])
        polygons = vtkCellArray()
        polygons.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True),
                         numpy_to_vtkIdTypeArray(connectivity, deep=True))
        surface.SetPolys(polygons)
    if all(name in data.point_data for name in ("nx", "ny", "nz")):
        normals = np.column_stack([data.point_data[name] for name in ("nx", "ny", "nz")]).astype(np.float64)
        array = numpy_to_vtk(np.ascontiguousarray(normals), deep=True)
        array.SetName("Normals")
        surface.GetPointData().SetNormals(array)
    return surface


def _point_normals(dataset):
    """(n, 3) float64 point normals stored in ``dataset``, or None."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    point_data = dataset.GetPointData()
    array = point_data.GetNormals()
    if array is None:
        array = next((point_data.GetArray(i) for i in range(point_data.GetNumberOfArrays())
                      if (point_data.GetArrayName(i) or "").lower() == "normals"), None)
    if array is None or array.GetNumberOfComponents() != 3:
        return None
    return np.array(vtk_to_numpy(array), dtype=np.float64).reshape(-1, 3)


def _normals_from_polygons(dataset):
    """(n, 3) consistent point normals computed from the polygons of ``dataset``, or None if it has none."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkFeatureEdges, vtkPolyDataNormals

    if isinstance(dataset, vtkPolyData):
        surface = dataset
    else:
        if dataset.GetNumberOfCells() == 0 or dataset.GetMaxCellSize() < 3 or _max_cell_dimension(dataset) != 2:
            return None
        from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter
        to_polydata = vtkGeometryFilter()
        to_polydata.SetInputData(dataset)
        to_polydata.Update()
        surface = to_polydata.GetOutput()
        if surface.GetNumberOfPoints() != dataset.GetNumberOfPoints():
            return None
    if surface.GetNumberOfPolys() + surface.GetNumberOfStrips() == 0:
        return None
    # AutoOrientNormals assumes a closed surface without non-manifold edges ("all bets are off" otherwise).
    edges = vtkFeatureEdges()
    edges.SetInputData(surface)
    edges.BoundaryEdgesOn()
    edges.NonManifoldEdgesOn()
    edges.FeatureEdgesOff()
    edges.ManifoldEdgesOff()
    edges.Update()
    closed_manifold = edges.GetOutput().GetNumberOfCells() == 0

    normals = vtkPolyDataNormals()
    normals.SetInputData(surface)
    normals.ComputePointNormalsOn()
    normals.ComputeCellNormalsOff()
    normals.SplittingOff()
    normals.ConsistencyOn()
    normals.NonManifoldTraversalOn()
    normals.SetAutoOrientNormals(closed_manifold)
    normals.Update()
    output = normals.GetOutput()
    array = output.GetPointData().GetNormals()
    if array is None or output.GetNumberOfPoints() != surface.GetNumberOfPoints():
        return None
    return np.array(vtk_to_numpy(array), dtype=np.float64).reshape(-1, 3)


def _max_cell_dimension(dataset) -> int:
    """Largest topological dimension among the cells of ``dataset`` (-1 when it has none)."""
    from vtkmodules.vtkCommonDataModel import vtkCellTypes, vtkGenericCell

    types = vtkCellTypes()
    if hasattr(dataset, "GetDistinctCellTypes"):  # VTK >= 9.6; GetCellTypes is deprecated there
        dataset.GetDistinctCellTypes(types)
    else:
        dataset.GetCellTypes(types)
    cell = vtkGenericCell()
    dimensions = [-1]
    for i in range(types.GetNumberOfTypes()):
        cell.SetCellType(types.GetCellType(i))
        dimensions.append(cell.GetCellDimension())
    return max(dimensions)
