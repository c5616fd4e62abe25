"""Reading scattered points and reading/writing meshes.

Points come from text tables (``.xyz``, ``.txt``, ``.csv``) or from VTK-readable files (``.vtp``, ``.vtk``,
``.vtu``, ``.ply``, ``.obj``, ``.stl``); meshes go through meshio (``.vtu``, ``.vtk``, ``.msh``, ``.inp``,
``.mesh``).  VTK is imported lazily, from ``vtkmodules.*`` only and with API present in VTK 9.2, so that this
module loads in ParaView 5.11 and Slicer.  VTK readers report failures by printing; here they are silenced and
every failure becomes an :class:`InvalidInputError` that names the file.
"""
from __future__ import annotations

import contextlib
import io as _stdio
import re
import warnings
from pathlib import Path

import numpy as np

from bitemesh.core.errors import InvalidInputError, check_points
from bitemesh.core.mesh import Mesh, signed_measures

TEXT_POINT_EXTENSIONS = (".xyz", ".txt", ".csv")
VTK_POINT_EXTENSIONS = (".vtp", ".vtk", ".vtu", ".ply", ".obj", ".stl")
POINT_EXTENSIONS = TEXT_POINT_EXTENSIONS + VTK_POINT_EXTENSIONS
MESH_EXTENSIONS = (".vtu", ".vtk", ".msh", ".inp", ".mesh")

#: meshio file format used for each mesh extension (``.msh`` is gmsh 2.2 ASCII, ``.vtk`` legacy 4.2 binary).
MESHIO_FORMATS = {".vtu": "vtu", ".vtk": "vtk42", ".msh": "gmsh22", ".inp": "abaqus", ".mesh": "medit"}

#: Integer cell arrays taken, in this order, as region labels (gmsh physical tag, medit reference) on writing.
REGION_ARRAYS = ("Label", "Region", "gmsh:physical", "medit:ref")

_TOKEN_SPLIT = re.compile(r"[\s,;]+")
_TEXT_COLUMNS = {2: (2, False), 3: (3, False), 4: (2, True), 6: (3, True)}


# --------------------------------------------------------------------------------------------- helpers


def _supported(extensions) -> str:
    return ", ".join(extensions)


def _existing_file(path, what: str, extensions) -> Path:
    """``path`` as a Path after checking that it is a readable, non-empty file with a known extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in extensions:
        raise InvalidInputError(
            f"cannot read {what} from '{path}': unknown extension {path.suffix or '(none)'!r}; "
            f"supported extensions: {_supported(extensions)}")
    if not path.exists():
        raise InvalidInputError(f"cannot read {what} from '{path}': the file does not exist")
    if not path.is_file():
        raise InvalidInputError(f"cannot read {what} from '{path}': it is not a regular file")
    try:
        with open(path, "rb") as stream:
            empty = not stream.read(1)
    except OSError as error:
        raise InvalidInputError(f"cannot read {what} from '{path}': {error.strerror or error}") from None
    if empty:
        raise InvalidInputError(f"cannot read {what} from '{path}': the file is empty")
    return path


def _unit_rows(vectors: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    lengths = np.linalg.norm(vectors, axis=1, keepdims=True)
    return np.divide(vectors, lengths, out=np.zeros_like(vectors), where=lengths > 0)


def _native(array) -> np.ndarray:
    """``array`` in native byte order (meshio's legacy VTK reader returns big-endian arrays)."""
    array = np.asarray(array)
    return array.astype(array.dtype.newbyteorder("="), copy=False) if array.dtype.byteorder not in "=|" else array


# --------------------------------------------------------------------------------------------- points


def read_points(path):
    """Read scattered points and, where the file has or implies them, point normals.

    Parameters
    ----------
    path : str or Path
        ``.xyz``, ``.txt``, ``.csv``: one point per row, columns ``x y [z] [nx ny [nz]]`` (2, 3, 4 or 6 numbers)
        separated by whitespace, commas or semicolons; leading non-numeric lines (headers) are skipped and ``#``
        starts a comment.  ``.vtp``, ``.vtk`` (legacy, also version 5.1), ``.vtu``, ``.ply``, ``.obj``, ``.stl``:
        the points of any VTK dataset; normals from the point normals (or a 3-component point array named
        ``Normals``) or, when the file has none but has polygons, computed from the polygons.

    Returns
    -------
    points : (n, k) float64, input units; k = 2 for a 2-column or 4-column text file, else 3
    normals : (n, k) float64 unit vectors (zero where undefined), or None when the file gives no normals and no
        polygons to compute them from.  Computed normals are consistent across each connected surface; they point
        outward for closed manifold surfaces and follow the polygon ordering of open ones.

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, no points, or a malformed text row (the message names
        the file and the line).
    """
    path = _existing_file(path, "points", POINT_EXTENSIONS)
    if path.suffix.lower() in TEXT_POINT_EXTENSIONS:
        return _read_text_points(path)
    return _read_vtk_points(path)


def _read_text_points(path: Path):
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        raise InvalidInputError(f"cannot read points from '{path}': {error.strerror or error}") from None
    lines = text.splitlines()
    table = _fast_table(lines, separators="," in text or ";" in text)
    if table is None:  # the line-by-line parser finds and names the faulty line
        table = _parse_table(lines, path)
    dim, has_normals = _TEXT_COLUMNS[table.shape[1]]
    points = check_points(table[:, :dim], f"points of '{path}'")
    normals = None
    if has_normals:
        normals = table[:, dim:]
        if not np.isfinite(normals).all():
            raise InvalidInputError(f"cannot read points from '{path}': the normal columns hold NaN or infinity")
        normals = _unit_rows(normals)
    return points, normals


def _tokens(line: str):
    return [token for token in _TOKEN_SPLIT.split(line.split("#", 1)[0].strip()) if token]


def _fast_table(lines, separators: bool):
    """The numeric rows after the header as an (n, c) array, by numpy's C parser; None if anything is off."""
    for start, line in enumerate(lines):
        tokens = _tokens(line)
        if tokens and all(_is_number(token) for token in tokens):
            break
    else:
        return None
    body = lines[start:]
    if separators:
        body = [line.replace(",", " ").replace(";", " ") for line in body]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. "input contained no data"
            table = np.loadtxt(body, dtype=np.float64, comments="#", ndmin=2)
    except ValueError:
        return None
    return table if len(table) and table.shape[1] in _TEXT_COLUMNS else None


def _parse_table(lines, path: Path) -> np.ndarray:
    """The numeric rows as an (n, c) array, line by line; raises naming the first bad line."""
    rows = []
    columns = None
    first_line = None
    first_text = None  # (line, token, mixed) of the first non-numeric line (a data row with text if possible)
    for number, line in enumerate(lines, start=1):
        tokens = _tokens(line)
        if not tokens:
            continue
        try:
            values = [float(token) for token in tokens]
        except ValueError:
            bad = next(token for token in tokens if not _is_number(token))
            if columns is None:
                mixed = any(_is_number(token) for token in tokens)
                if first_text is None or (mixed and not first_text[2]):
                    first_text = (number, bad, mixed)
                continue  # header line before the data
            raise InvalidInputError(
                f"cannot read points from '{path}': line {number} has the non-numeric value {bad!r}; "
                f"after the header every row must hold only numbers ({columns} columns, as on line {first_line})"
            ) from None
        if columns is None:
            if len(values) not in _TEXT_COLUMNS:
                raise InvalidInputError(
                    f"cannot read points from '{path}': line {number} has {len(values)} columns; expected "
                    "2 (x y), 3 (x y z), 4 (x y nx ny) or 6 (x y z nx ny nz)")
            columns, first_line = len(values), number
        elif len(values) != columns:
            raise InvalidInputError(
                f"cannot read points from '{path}': line {number} has {len(values)} columns but line "
                f"{first_line} has {columns}; every row must have the same number of columns")
        rows.append(values)
    if not rows:
        where = (f"; line {first_text[0]} has the non-numeric value {first_text[1]!r}" if first_text else "")
        raise InvalidInputError(
            f"cannot read points from '{path}': no row holds only numbers (no points){where}")
    return np.array(rows, dtype=np.float64)


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


@contextlib.contextmanager
def _vtk_silenced():
    """Stop VTK from printing errors and warnings (readers print instead of raising); restore afterwards."""
    from vtkmodules.vtkCommonCore import vtkObject

    previous = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        yield
    finally:
        vtkObject.SetGlobalWarningDisplay(previous)


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
        with _vtk_silenced():
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
    coordinates = np.array(vtk_to_numpy(points.GetData()), dtype=np.float64).reshape(-1, 3)
    coordinates = check_points(coordinates, f"points of '{path}'", dims=(3,))
    normals = _point_normals(dataset)
    if normals is None:
        with _vtk_silenced():
            normals = _normals_from_polygons(dataset)
        if normals is not None:
            # a surface's points that no polygon uses (duplicates, strays) have no normal: leave them out
            used = np.any(normals != 0, axis=1)
            coordinates, normals = coordinates[used], normals[used]
    if normals is not None:
        normals = _unit_rows(np.where(np.isfinite(normals), normals, 0.0))
    return coordinates, normals


def _read_ply(path: Path):
    """The PLY file as a vtkPolyData (points, polygons, normals from ``nx ny nz``), parsed by meshio.

    Not vtkPLYReader: it crashes the interpreter (segmentation fault) on a truncated binary file.
    """
    import meshio
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    with _meshio_warnings():
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


# --------------------------------------------------------------------------------------------- labelled points

LABELLED_TEXT_EXTENSIONS = (".txt", ".csv", ".tsv")
LABELLED_VTK_EXTENSIONS = (".vtp", ".vtk", ".vtu")
LABELLED_EXTENSIONS = LABELLED_TEXT_EXTENSIONS + LABELLED_VTK_EXTENSIONS
#: header names (lower case) of the label column, first match wins; a GPFile's is "contour type".
LABEL_COLUMNS = ("label", "labels", "contour type", "contour_type", "contourtype", "type", "region", "surface")
#: header names (lower case) of the optional slice column; a GPFile's is "frameID".
SLICE_COLUMNS = ("frameid", "frame_id", "slice", "sliceid", "slice_id", "slice id")


def read_labelled_points(path, *, slices: bool = False):
    """Read contour points with a label per point: a biv-me GPFile, a CSV table, or a VTK file with a Label array.

    Parameters
    ----------
    path : str or Path
        ``.txt``, ``.csv``, ``.tsv``: a table, one point per row, fields separated by tabs (a biv-me GPFile:
        header ``x y z contour type frameID weight time frame``), commas, semicolons or spaces.  With a header row,
        the columns are found by name: ``x``, ``y``, ``z`` (else the first three), the label (``label``,
        ``contour type``, ``type``, ``region`` or ``surface``; else the fourth column) and, optionally, the slice
        (``frameID`` or ``slice``).  Without a header: ``x y z label [slice]``.  Labels are strings or integers;
        ``#`` starts a comment line.
        ``.vtp``, ``.vtk``, ``.vtu``: the points of the dataset and its point-data array ``Label`` (integer or
        string), and optionally ``Slice`` or ``FrameID``.
    slices : bool
        Also return the slice id of each point.

    Returns
    -------
    points : (n, 3) float64, input units
    labels : (n,) str array (integer labels as their decimal text, "1")
    slice_ids : (n,) int64, only with ``slices=True``; None when the file has no slice column or array

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, no label column or array, a malformed row (the
        message names the file and the line), an empty label, or no points.
    """
    path = _existing_file(path, "labelled points", LABELLED_EXTENSIONS)
    if path.suffix.lower() in LABELLED_TEXT_EXTENSIONS:
        points, labels, slice_ids = _read_labelled_table(path)
    else:
        points, labels, slice_ids = _read_labelled_vtk(path)
    labels = _label_text(labels)
    empty = labels == ""
    if empty.any():
        raise InvalidInputError(f"cannot read labelled points from '{path}': {int(empty.sum())} points have an "
                                f"empty label (first: point {int(np.argmax(empty))})")
    return (points, labels, slice_ids) if slices else (points, labels)


def looks_labelled(path) -> bool:
    """True when ``path`` holds labelled points for :func:`read_labelled_points`: a table whose header names a
    label column (a GPFile's ``contour type``) or whose first row's fourth field is not a number, or a VTK file
    with a ``Label`` point array.  False for anything else, including unreadable files (let the reader say why)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix in LABELLED_TEXT_EXTENSIONS:
            with open(path, encoding="utf-8-sig", errors="replace") as stream:
                first = next((line for line in stream if line.strip() and not line.lstrip().startswith("#")), "")
            delimiter = next((mark for mark in ("\t", ",", ";") if mark in first), None)
            fields = _split_fields(first, delimiter)
            if len(fields) >= 3 and not all(_is_number(field) for field in fields[:3]):
                return any(field.lower() in LABEL_COLUMNS for field in fields)
            return len(fields) >= 4 and not _is_number(fields[3])
        if suffix in LABELLED_VTK_EXTENSIONS:
            with _vtk_silenced():
                reader = _vtk_reader(path)
                reader.GetExecutive().Update()
                dataset = reader.GetOutputDataObject(0)
            from .algorithms.convert import LABEL_ARRAYS, named_point_array
            return dataset is not None and hasattr(dataset, "GetPointData") and \
                named_point_array(dataset, LABEL_ARRAYS) is not None
    except (OSError, InvalidInputError):
        return False
    return False


def _label_text(labels) -> np.ndarray:
    """Labels as a str array; numbers that are whole ("2", "2.0", 2) become their integer text ("2")."""
    text = np.array([str(label).strip() for label in np.asarray(labels).tolist()], dtype=object)
    try:
        values = np.array([float(label) for label in text])
    except ValueError:
        return text.astype(str)
    if np.isfinite(values).all() and np.all(values == np.round(values)):
        return np.array([str(int(value)) for value in values], dtype=str)
    return text.astype(str)


def _split_fields(line: str, delimiter):
    return [field.strip() for field in (line.split(delimiter) if delimiter else line.split())]


def _read_labelled_table(path: Path):
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as error:
        raise InvalidInputError(f"cannot read labelled points from '{path}': {error.strerror or error}") from None
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InvalidInputError(f"cannot read labelled points from '{path}': the file has no rows")
    first = lines[0][1]
    delimiter = next((mark for mark in ("\t", ",", ";") if mark in first), None)
    fields = _split_fields(first, delimiter)
    header = len(fields) >= 3 and not all(_is_number(field) for field in fields[:3])
    if header:
        names = [field.lower() for field in fields]
        coordinates = [names.index(axis) if axis in names else axis_number for axis_number, axis in
                       enumerate("xyz")]
        label_column = next((names.index(name) for name in LABEL_COLUMNS if name in names), None)
        if label_column is None:
            label_column = 3 if len(names) > 3 and 3 not in coordinates else None
        if label_column is None:
            raise InvalidInputError(
                f"cannot read labelled points from '{path}': the header {fields} names no label column; name it "
                f"one of {', '.join(LABEL_COLUMNS)}")
        slice_column = next((names.index(name) for name in SLICE_COLUMNS if name in names), None)
        width = len(fields)
        rows = lines[1:]
    else:
        width = len(fields)
        if width < 4:
            raise InvalidInputError(
                f"cannot read labelled points from '{path}': line {lines[0][0]} has {width} fields; a labelled "
                "point needs x y z label [slice] (or a header naming the columns)")
        coordinates, label_column, slice_column = [0, 1, 2], 3, (4 if width > 4 else None)
        rows = lines
    if not rows:
        raise InvalidInputError(f"cannot read labelled points from '{path}': the file has a header but no points")
    points = np.empty((len(rows), 3))
    labels = []
    slice_ids = np.empty(len(rows), dtype=np.int64) if slice_column is not None else None
    for row, (number, line) in enumerate(rows):
        values = _split_fields(line, delimiter)
        if len(values) < width:
            raise InvalidInputError(
                f"cannot read labelled points from '{path}': line {number} has {len(values)} fields, the "
                f"{'header' if header else 'first row'} has {width}")
        try:
            points[row] = [float(values[column]) for column in coordinates]
        except ValueError:
            bad = next(values[column] for column in coordinates if not _is_number(values[column]))
            raise InvalidInputError(
                f"cannot read labelled points from '{path}': line {number} has the coordinate {bad!r}, not a "
                "number") from None
        labels.append(values[label_column])
        if slice_ids is not None:
            try:
                slice_ids[row] = int(float(values[slice_column]))
            except ValueError:
                raise InvalidInputError(
                    f"cannot read labelled points from '{path}': line {number} has the slice id "
                    f"{values[slice_column]!r}, not an integer") from None
    points = check_points(points, f"points of '{path}'", dims=(3,))
    return points, labels, slice_ids


def _read_labelled_vtk(path: Path):
    with _vtk_silenced():
        reader = _vtk_reader(path)
        succeeded = reader.GetExecutive().Update()
        dataset = reader.GetOutputDataObject(0)
    if not succeeded or reader.GetErrorCode() or dataset is None or not hasattr(dataset, "GetPoints") \
            or dataset.GetPoints() is None or dataset.GetNumberOfPoints() == 0:
        raise InvalidInputError(
            f"cannot read labelled points from '{path}': the {reader.GetClassName()} read no points; is the file "
            "truncated, or not of the format its extension says?")
    from .algorithms.convert import point_coordinates, point_labels

    points = check_points(point_coordinates(dataset), f"points of '{path}'", dims=(3,))
    labels, slice_ids = point_labels(dataset, f"cannot read labelled points from '{path}'")
    if labels is None:
        data = dataset.GetPointData()
        present = [data.GetArrayName(i) for i in range(data.GetNumberOfArrays())]
        raise InvalidInputError(
            f"cannot read labelled points from '{path}': it has no one-component point array named 'Label' "
            f"(point arrays present: {', '.join(map(str, present)) or 'none'})")
    return points, labels, slice_ids


#: the keys a labelled-domain config file may hold, with the type each value must have.
LABELLED_CONFIG_KEYS = {"domain": "str", "surfaces": "{name: [labels]}", "base_plane":
                        "'auto', 'valves', 'none', null or {point: [x, y, z], normal: [x, y, z]}",
                        "base_offset": "number", "outlets": "{surface: [valve labels]}", "min_wall": "number",
                        "kernel": "str", "offset": "number"}


def read_labelled_config(path) -> dict:
    """Read a small JSON or TOML file that says which domain to mesh from labelled contours.

    Example (JSON)::

        {"surfaces": {"EPI": ["SAX_LV_EPICARDIAL", "LAX_LV_EPICARDIAL"], "LV_ENDO": ["SAX_LV_ENDOCARDIAL"]},
         "domain": "EPI - LV_ENDO", "base_plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "min_wall": 2.0}

    Keys (all optional): see :data:`LABELLED_CONFIG_KEYS`; they are the keyword arguments of
    :func:`bitemesh.core.labelled.labelled_implicit` and ``run_labelled``.

    Returns
    -------
    dict of those keyword arguments, ``base_plane`` as None, a string or a (point, normal) pair

    Raises
    ------
    InvalidInputError
        Missing or unreadable file, a syntax error (with the parser's message), an unknown key (the message lists
        the known ones) or a value of the wrong type.
    """
    path = _existing_file(path, "a labelled-domain config", (".json", ".toml"))
    try:
        text = path.read_text(encoding="utf-8")
        if path.suffix.lower() == ".json":
            import json
            config = json.loads(text)
        else:
            try:
                import tomllib
            except ImportError:   # Python < 3.11
                raise InvalidInputError(f"cannot read '{path}': TOML needs Python 3.11 or later; use JSON") from None
            config = tomllib.loads(text)
    except InvalidInputError:
        raise
    except (OSError, ValueError) as error:
        raise InvalidInputError(f"cannot read a labelled-domain config from '{path}': {error}") from None
    if not isinstance(config, dict):
        raise InvalidInputError(f"'{path}' must hold a table (an object) of settings, got {type(config).__name__}")
    unknown = sorted(set(config) - set(LABELLED_CONFIG_KEYS))
    if unknown:
        raise InvalidInputError(f"'{path}': unknown key(s) {', '.join(unknown)}; known keys: "
                                f"{', '.join(LABELLED_CONFIG_KEYS)}")

    def fail(key):
        raise InvalidInputError(f"'{path}': {key} must be {LABELLED_CONFIG_KEYS[key]}, got {config[key]!r}")

    def label_lists(key):
        value = config[key]
        if not isinstance(value, dict) or not all(
                isinstance(members, (str, int)) or (isinstance(members, list) and members
                                                    and all(isinstance(m, (str, int)) for m in members))
                for members in value.values()):
            fail(key)
        return {str(name): [str(m) for m in (members if isinstance(members, list) else [members])]
                for name, members in value.items()}

    result = {}
    for key, value in config.items():
        if key in ("domain", "kernel"):
            if not isinstance(value, str):
                fail(key)
            result[key] = value
        elif key in ("base_offset", "min_wall", "offset"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                fail(key)
            result[key] = float(value)
        elif key in ("surfaces", "outlets"):
            result[key] = label_lists(key)
        else:   # base_plane
            if value is None or value in ("auto", "valves", "none"):
                result[key] = None if value in (None, "none") else value
            elif isinstance(value, dict) and set(value) == {"point", "normal"}:
                result[key] = (value["point"], value["normal"])
            else:
                fail(key)
    return result


# --------------------------------------------------------------------------------------------- meshes


def write_mesh(mesh: Mesh, path) -> None:
    """Write a triangle (2D) or tetrahedral (3D) mesh, the format chosen by the extension of ``path``.

    ``.vtu`` (VTK XML, binary, zlib), ``.vtk`` (legacy VTK 4.2, binary), ``.msh`` (gmsh 2.2 ASCII), ``.inp``
    (Abaqus), ``.mesh`` (MEDIT ASCII), all through meshio.  VTK and gmsh get z = 0 for a 2D mesh.
    Cell data: ``.vtu``/``.vtk`` keep every array; ``.msh`` and ``.mesh`` keep only the region labels, the first
    1-D integer array named in :data:`REGION_ARRAYS`, as the gmsh physical and elementary tags (1 when there is
    none) or as the MEDIT reference; ``.inp`` keeps none.

    Parameters
    ----------
    mesh : Mesh
        points (n, k) float64 with k = 2 or 3, cells (m, k + 1) int, cell_data name -> (m, ...) arrays.
    path : str or Path
        The output file; its directory must exist.  Overwritten if present.
    """
    import meshio

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESHIO_FORMATS:
        raise InvalidInputError(
            f"cannot write a mesh to '{path}': unknown extension {path.suffix or '(none)'!r}; "
            f"supported extensions: {_supported(MESH_EXTENSIONS)}")
    points, cells, cell_data = _checked_mesh(mesh)
    dim = points.shape[1]
    if dim == 2 and suffix in (".vtu", ".vtk", ".msh"):
        points = np.column_stack([points, np.zeros(len(points))])
    regions = _region_labels(cell_data)
    if suffix == ".msh":
        # Only the tags: meshio 5.3 writes ASCII $ElementData values as numpy reprs ("np.int32(1)") under numpy 2,
        # which no reader (meshio included) can parse.
        tags = regions if regions is not None else np.ones(len(cells), dtype=np.int32)
        data = {"gmsh:physical": tags, "gmsh:geometrical": tags}
    elif suffix == ".mesh":
        data = {"medit:ref": regions} if regions is not None else {}
    elif suffix == ".inp":
        data = {}
    else:
        data = {name: (array.astype(np.uint8) if array.dtype == bool else array)
                for name, array in cell_data.items()}
    cell_type = "triangle" if dim == 2 else "tetra"
    meshio_mesh = meshio.Mesh(points, [(cell_type, cells)],
                              cell_data={name: [array] for name, array in data.items()})
    options = {"binary": False} if suffix == ".msh" else {}
    if not path.parent.is_dir():
        raise InvalidInputError(f"cannot write a mesh to '{path}': the directory '{path.parent}' does not exist")
    with _meshio_warnings():
        try:
            meshio.write(path, meshio_mesh, file_format=MESHIO_FORMATS[suffix], **options)
        except OSError as error:
            raise InvalidInputError(f"cannot write a mesh to '{path}': {error.strerror or error}") from None


def _checked_mesh(mesh):
    if not all(hasattr(mesh, name) for name in ("points", "cells", "cell_data")):
        raise InvalidInputError(f"mesh must be a bitemesh Mesh (points, cells, cell_data), got {type(mesh).__name__}")
    points = check_points(mesh.points, "mesh.points")
    cells = np.asarray(mesh.cells)
    dim = points.shape[1]
    if cells.ndim != 2 or cells.shape[1] != dim + 1 or (cells.size and cells.dtype.kind not in "iu"):
        raise InvalidInputError(
            f"mesh.cells must be an (m, {dim + 1}) integer array for {dim}D points, got shape {cells.shape} "
            f"of {cells.dtype}")
    cells = cells.astype(np.int64)
    if cells.size and (cells.min() < 0 or cells.max() >= len(points)):
        raise InvalidInputError(
            f"mesh.cells must index mesh.points (0..{len(points) - 1}), got values in "
            f"[{cells.min()}, {cells.max()}]")
    cell_data = {}
    for name, array in (mesh.cell_data or {}).items():
        array = np.asarray(array)
        if array.ndim == 0 or len(array) != len(cells):
            raise InvalidInputError(
                f"mesh.cell_data[{name!r}] must have one row per cell ({len(cells)}), got shape {array.shape}")
        cell_data[str(name)] = _native(array)
    return points, cells, cell_data


def _region_labels(cell_data):
    """(m,) int32 region labels from the first integer array in :data:`REGION_ARRAYS`, or None."""
    for name in REGION_ARRAYS:
        array = cell_data.get(name)
        if array is not None and array.ndim == 1 and array.dtype.kind in "iub":
            return array.astype(np.int32)
    return None


@contextlib.contextmanager
def _meshio_warnings():
    """Turn what meshio prints on stderr (through rich) into Python warnings."""
    captured = _stdio.StringIO()
    with contextlib.redirect_stderr(captured):
        yield
    text = " ".join(captured.getvalue().split())
    if text:
        warnings.warn(f"meshio: {text}", stacklevel=3)


def read_mesh(path, *, orient: bool = True) -> Mesh:
    """Read a tetrahedral mesh, or a planar triangle mesh, with meshio.

    Parameters
    ----------
    path : str or Path
        ``.vtu``, ``.vtk`` (legacy 4.2 or 5.1), ``.msh`` (gmsh 2.2 or 4.x, ASCII or binary; not ANSYS),
        ``.inp`` (Abaqus), ``.mesh`` (MEDIT).
    orient : bool
        Reorder the vertices of negatively oriented cells so that every cell is positively oriented (the
        :class:`Mesh` convention).

    Returns
    -------
    Mesh
        The linear tetrahedra of the file (every ``tetra`` block, in file order) and all its points (unused
        points are kept, so indices match the file).  A file with no tetrahedra but triangles whose points are
        2D or share one z value gives a 2D mesh: points (n, 2) (z dropped), triangle cells.  Cell data given by
        meshio for every selected block are carried over under meshio's names (e.g. ``gmsh:physical``,
        ``medit:ref``), in native byte order.

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, or no tetrahedra / planar triangles.
    """
    import meshio

    path = _existing_file(path, "a mesh", MESH_EXTENSIONS)
    # The per-format readers, not meshio.read: that one prints the error and calls sys.exit(1) on a bad file.
    readers = {".vtu": meshio.vtu.read, ".vtk": meshio.vtk.read, ".msh": meshio.gmsh.read,
               ".inp": meshio.abaqus.read, ".mesh": meshio.medit.read}
    reader = readers[path.suffix.lower()]
    with _meshio_warnings():
        try:
            data = reader(str(path))
        except Exception as error:  # meshio raises ReadError, ValueError, IndexError, ... on bad files
            raise InvalidInputError(
                f"cannot read a mesh from '{path}': {type(error).__name__}: {error}") from error
    points = np.array(_native(data.points), dtype=np.float64)
    if points.ndim != 2 or len(points) == 0:
        raise InvalidInputError(f"cannot read a mesh from '{path}': the file has no points")
    kinds = [block.type for block in data.cells]
    if "tetra" in kinds:
        cell_type = "tetra"
        points = points[:, :3] if points.shape[1] >= 3 else None
        if points is None:
            raise InvalidInputError(f"cannot read a mesh from '{path}': tetrahedra need 3D points")
    elif "triangle" in kinds and (points.shape[1] == 2 or _planar_z(points)):
        cell_type = "triangle"
        points = points[:, :2]
    else:
        found = ", ".join(sorted(set(kinds))) or "no cells"
        raise InvalidInputError(
            f"cannot read a mesh from '{path}': it has no linear tetrahedra and no planar triangles (found: "
            f"{found}); read_mesh reads volume meshes and 2D triangle meshes")
    chosen = [i for i, kind in enumerate(kinds) if kind == cell_type]
    cells = np.concatenate([_native(data.cells[i].data) for i in chosen]).astype(np.int64)
    cell_data = {}
    for name, blocks in data.cell_data.items():
        try:
            arrays = [_native(blocks[i]) for i in chosen]
            cell_data[name] = np.concatenate(arrays)
        except (IndexError, TypeError, ValueError):
            continue  # this array is missing on some of the chosen blocks
    points = check_points(points, f"points of '{path}'")
    if cells.size and (cells.min() < 0 or cells.max() >= len(points)):
        raise InvalidInputError(f"cannot read a mesh from '{path}': cells index points that do not exist")
    if orient and len(cells):
        negative = signed_measures(points, cells) < 0
        cells[negative, :2] = cells[negative, 1::-1]
    return Mesh(points, cells, cell_data)


def _planar_z(points: np.ndarray) -> bool:
    """True for (n, 3) points that share one z value (to rounding)."""
    if points.shape[1] < 3:
        return True
    z = points[:, 2]
    scale = max(float(np.ptp(points[:, :2], axis=0).max(initial=0.0)), float(np.abs(z).max(initial=0.0)), 1.0)
    return float(np.ptp(z)) <= 1e-12 * scale
