"""Tetrahedral (and 2D triangle) meshes to and from files, through meshio; every write is atomic.

``.vtu`` (VTK XML), ``.vtk`` (legacy), ``.msh`` (gmsh), ``.inp`` (Abaqus), ``.mesh`` (MEDIT).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError, check_points
from ..core.mesh import Mesh, signed_measures
from .files import atomic_output, existing_file, meshio_warnings, native, supported

MESH_EXTENSIONS = (".vtu", ".vtk", ".msh", ".inp", ".mesh")

#: meshio file format used for each mesh extension (``.msh`` is gmsh 2.2 ASCII, ``.vtk`` legacy 4.2 binary).
MESHIO_FORMATS = {".vtu": "vtu", ".vtk": "vtk42", ".msh": "gmsh22", ".inp": "abaqus", ".mesh": "medit"}

#: Integer cell arrays taken, in this order, as region labels (gmsh physical tag, medit reference) on writing.
REGION_ARRAYS = ("Label", "Region", "gmsh:physical", "medit:ref")



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
        The output file; its directory must exist.  Written to a temporary file beside it, then renamed onto it:
        a failed or interrupted write leaves the previous file as it was (or no file).
    """
    import meshio

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESHIO_FORMATS:
        raise InvalidInputError(
            f"cannot write a mesh to '{path}': unknown extension {path.suffix or '(none)'!r}; "
            f"supported extensions: {supported(MESH_EXTENSIONS)}")
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
    with atomic_output(path) as temporary, meshio_warnings():
        meshio.write(temporary, meshio_mesh, file_format=MESHIO_FORMATS[suffix], **options)


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
        cell_data[str(name)] = native(array)
    return points, cells, cell_data


def _region_labels(cell_data):
    """(m,) int32 region labels from the first integer array in :data:`REGION_ARRAYS`, or None."""
    for name in REGION_ARRAYS:
        array = cell_data.get(name)
        if array is not None and array.ndim == 1 and array.dtype.kind in "iub":
            return array.astype(np.int32)
    return None


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

    path = existing_file(path, "a mesh", MESH_EXTENSIONS)
    # The per-format readers, not meshio.read: that one prints the error and calls sys.exit(1) on a bad file.
    readers = {".vtu": meshio.vtu.read, ".vtk": meshio.vtk.read, ".msh": meshio.gmsh.read,
               ".inp": meshio.abaqus.read, ".mesh": meshio.medit.read}
    reader = readers[path.suffix.lower()]
    with meshio_warnings():
        try:
            data = reader(str(path))
        except Exception as error:  # meshio raises ReadError, ValueError, IndexError, ... on bad files
            data = _read_with_vtk(path) if path.suffix.lower() in (".vtu", ".vtk") else None
            if data is None:
                reason = f"{type(error).__name__}: {error}" if str(error).strip() else type(error).__name__
                raise InvalidInputError(
                    f"cannot read a mesh from '{path}': meshio could not parse it ({reason}); is the file "
                    "truncated, or not of the format its extension says?") from error
    points = np.array(native(data.points), dtype=np.float64)
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
    cells = np.concatenate([native(data.cells[i].data) for i in chosen]).astype(np.int64)
    cell_data = {}
    for name, blocks in data.cell_data.items():
        try:
            arrays = [native(blocks[i]) for i in chosen]
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


def _read_with_vtk(path: Path):
    """The file read by VTK's own reader, as meshio would give it (points, cells, cell data), or None when VTK
    cannot read it either.  meshio 5.3 misreads valid files that VTK writes: raw appended data with field data
    (ParaView's default for .vtu) shifts its offsets."""
    import meshio
    from vtkmodules.util.numpy_support import vtk_to_numpy

    from ..convert import cell_types
    from .files import vtk_silenced
    from .pointsets import _vtk_reader

    with vtk_silenced():
        try:
            reader = _vtk_reader(path)
        except InvalidInputError:
            return None
        succeeded = reader.GetExecutive().Update()
        grid = reader.GetOutputDataObject(0)
    if not succeeded or reader.GetErrorCode() or grid is None or not grid.IsA("vtkUnstructuredGrid"):
        return None
    cells = grid.GetCells()
    offsets = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    connectivity = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    types = cell_types(grid)
    blocks, data = [], {}
    for name, vtk_type, size in (("tetra", 10, 4), ("triangle", 5, 3)):
        chosen = np.flatnonzero(types == vtk_type)
        if chosen.size:
            blocks.append((name, connectivity[offsets[chosen][:, None] + np.arange(size)]))
            for index in range(grid.GetCellData().GetNumberOfArrays()):
                array = grid.GetCellData().GetArray(index)
                if array is not None and array.GetName():
                    data.setdefault(array.GetName(), []).append(vtk_to_numpy(array)[chosen].copy())
    points = vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64) if grid.GetPoints() else np.zeros((0, 3))
    return meshio.Mesh(points, blocks, cell_data={name: arrays for name, arrays in data.items()
                                                  if len(arrays) == len(blocks)})


def _planar_z(points: np.ndarray) -> bool:
    """True for (n, 3) points that share one z value (to rounding)."""
    if points.shape[1] < 3:
        return True
    z = points[:, 2]
    scale = max(float(np.ptp(points[:, :2], axis=0).max(initial=0.0)), float(np.abs(z).max(initial=0.0)), 1.0)
    return float(np.ptp(z)) <= 1e-12 * scale
