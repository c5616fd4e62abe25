"""Reading tetrahedral (and 2D triangle) meshes with their tags, from every format :mod:`.meshes` writes (and gmsh 4,
legacy VTK 5.1): what each holds is :mod:`.meshes`' docstring."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError, check_points
from ..core.mesh.simplicial import MAX_DIMENSION, Mesh, signed_measures
from .abaqus import read_abaqus_tags
from .files import existing_file, meshio_warnings, native
from .folders import read_folder
from .meshes import ANY_DIMENSION, FACET_ARRAY, MESH_EXTENSIONS, TAG_ARRAYS, facet_file
from .opencarp import read_opencarp


def read_mesh(path, *, orient: bool = True) -> Mesh:
    """Read a tetrahedral mesh, or a planar triangle mesh, with its tags.

    Parameters
    ----------
    path : str or Path
        ``.vtu`` (with ``<stem>_facets.vtu`` if it is there), ``.vtk`` (legacy 4.2 or 5.1), ``.msh`` (gmsh 2.2 or
        4.x, ASCII or binary; not ANSYS), ``.inp`` (Abaqus), ``.mesh`` (MEDIT), ``.xdmf`` (one grid a file, with
        ``<stem>_facets.xdmf`` if it is there), read with meshio; ``.npz`` and ``.h5`` as bitemesh writes them, a
        mesh of any dimension.
    orient : bool
        Reorder the vertices of negatively oriented cells so that every cell is positively oriented (the
        :class:`Mesh` convention).  Facets keep the orientation the file gives them.

    Returns
    -------
    Mesh
        The linear tetrahedra of the file (every ``tetra`` block, in file order) and all its points (unused
        points are kept, so indices match the file).  A file with no tetrahedra but triangles whose points are
        2D or share one z value gives a 2D mesh: points (n, 2) (z dropped), triangle cells.  Cell data given by
        meshio for every selected block are carried over (in native byte order), the regions as ``Region`` (int32:
        the gmsh physical tags, the MEDIT references, the Abaqus region sets).  The facets (triangles, edges in 2D)
        with a tag > 0 become ``facets`` and ``facet_tags`` (None when there are none), the names ``tag_names``.

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, no tetrahedra / planar triangles, or a facet file
        that does not fit its mesh.
    """
    if Path(path).is_dir():
        points, cells, cell_data, facets, tags, names, unit = read_folder(Path(path))
        return _read_mesh(path, check_points(points, f"points of '{path}'"), cells, cell_data, facets, tags, names,
                          orient, unit=unit)
    path = existing_file(path, "a mesh", MESH_EXTENSIONS)
    suffix = path.suffix.lower()
    if suffix in ANY_DIMENSION:
        return _read_arrays(path, orient)
    if suffix == ".pts":
        points, cells, cell_data, facets, tags, names = read_opencarp(path)
        return _read_mesh(path, check_points(points, f"points of '{path}'"), cells, cell_data, facets, tags, names,
                          orient)
    data = _read_file(path)
    points = np.array(native(data.points), dtype=np.float64)
    if points.ndim != 2 or len(points) == 0:
        raise InvalidInputError(f"cannot read a mesh from '{path}': the file has no points")
    kinds = [block.type for block in data.cells]
    if "tetra" in kinds:
        cell_type, facet_type = "tetra", "triangle"
        points = points[:, :3] if points.shape[1] >= 3 else None
        if points is None:
            raise InvalidInputError(f"cannot read a mesh from '{path}': tetrahedra need 3D points")
    elif "triangle" in kinds and (points.shape[1] == 2 or _planar_z(points)):
        cell_type, facet_type = "triangle", "line"
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
            cell_data[name] = np.concatenate([native(blocks[i]) for i in chosen])
        except (IndexError, TypeError, ValueError):
            continue  # this array is missing on some of the chosen blocks
    points = check_points(points, f"points of '{path}'")
    region_array = TAG_ARRAYS.get(suffix, "Region")
    if region_array in cell_data:
        cell_data["Region"] = cell_data.pop(region_array).astype(np.int32)
    cell_data.pop("gmsh:geometrical", None)
    if suffix == ".inp":
        regions, facets, tags, names = read_abaqus_tags(path, data, chosen, points, cells)
        if regions is not None:
            cell_data["Region"] = regions
    else:
        facets, tags, names = _tagged_facets(data, facet_type, TAG_ARRAYS.get(suffix, FACET_ARRAY))
    if suffix in (".vtu", ".xdmf") and facet_file(path).is_file():
        facets, tags, names = _joined(path, facet_file(path), len(points), facet_type, (facets, tags, names))
    point_data = {name: native(array) for name, array in data.point_data.items()
                  if suffix in (".vtu", ".vtk", ".xdmf") and len(array) == len(points)} if data.point_data else {}
    return _read_mesh(path, points, cells, cell_data, facets, tags, names, orient, point_data,
                      xdmf_unit(path) if suffix == ".xdmf" else "mm")


def _read_arrays(path: Path, orient: bool) -> Mesh:
    """The mesh of a ``.npz`` or ``.h5`` file written by :func:`~.meshes.write_mesh` (any dimension)."""
    suffix = path.suffix.lower()
    try:
        arrays = _stored_arrays(path, suffix)
        points = check_points(arrays.pop("points"), f"points of '{path}'", dims=range(2, MAX_DIMENSION + 1))
        cells, facets = arrays.pop("cells").astype(np.int64), arrays.pop("facets").astype(np.int64)
        tags, names = arrays.pop("facet_tags").astype(np.int32), json.loads(str(arrays.pop("tag_names")))
        unit = str(arrays.pop("unit"))
    except (OSError, ValueError, KeyError, EOFError) as error:
        raise InvalidInputError(f"cannot read a mesh from '{path}': not a bitemesh {suffix} mesh ({error})") from error
    if cells.ndim != 2 or cells.shape[1] != points.shape[1] + 1:
        raise InvalidInputError(f"cannot read a mesh from '{path}': cells of shape {cells.shape} for "
                                f"{points.shape[1]}-D points")
    data = {kind: {name.split("/", 1)[1]: array for name, array in arrays.items() if name.startswith(kind + "/")}
            for kind in ("cell_data", "point_data")}
    return _read_mesh(path, points, cells, data["cell_data"], facets, tags,
                      {name: tuple(value) for name, value in names.items()}, orient, data["point_data"], unit)


def _stored_arrays(path: Path, suffix: str) -> dict:
    """name -> array of a ``.npz`` file, or of a ``.h5`` file's datasets (``group/name``) and attributes."""
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return {name: data[name] for name in data.files}
    import h5py
    arrays = {}
    with h5py.File(path, "r") as h5:
        h5.visititems(lambda name, item: arrays.update({name: item[()]}) if isinstance(item, h5py.Dataset) else None)
        arrays.update({name: str(value) for name, value in h5.attrs.items()})
    return arrays


def xdmf_unit(path: Path) -> str:
    """The unit an .xdmf file of bitemesh's names (its Geometry's ``Unit``), else mm."""
    import xml.etree.ElementTree as ET

    found = ET.parse(path).getroot().find(".//Geometry")
    return found.get("Unit", "mm") if found is not None else "mm"


def _read_mesh(path, points, cells, cell_data, facets, tags, names, orient: bool, point_data=None,
               unit: str = "mm") -> Mesh:
    """The Mesh of what a file gave, its indices checked, its cells positively oriented with ``orient``."""
    for what, table in (("cells", cells), ("facets", facets)):
        if table is not None and table.size and (table.min() < 0 or table.max() >= len(points)):
            raise InvalidInputError(f"cannot read a mesh from '{path}': {what} index points that do not exist")
    if orient and len(cells):
        negative = signed_measures(points, cells) < 0
        cells[negative, :2] = cells[negative, 1::-1]
    found = facets is not None and len(facets)
    return Mesh(points, cells, cell_data, facets if found else None, tags if found else None, names,
                point_data or {}, unit)


def _read_file(path: Path):
    """What meshio (or, for a VTK file meshio misreads, VTK) reads from ``path``."""
    import meshio

    # The per-format readers, not meshio.read: that one prints the error and calls sys.exit(1) on a bad file.
    readers = {".vtu": meshio.vtu.read, ".vtk": meshio.vtk.read, ".msh": meshio.gmsh.read,
               ".inp": meshio.abaqus.read, ".mesh": meshio.medit.read, ".xdmf": meshio.xdmf.read}
    with meshio_warnings():
        try:
            return readers[path.suffix.lower()](str(path))
        except Exception as error:  # meshio raises ReadError, ValueError, IndexError, ... on bad files
            data = _read_with_vtk(path) if path.suffix.lower() in (".vtu", ".vtk") else None
            if data is None:
                reason = f"{type(error).__name__}: {error}" if str(error).strip() else type(error).__name__
                raise InvalidInputError(
                    f"cannot read a mesh from '{path}': meshio could not parse it ({reason}); is the file "
                    "truncated, or not of the format its extension says?") from error
            return data


def _tagged_facets(data, facet_type: str, tag_array: str):
    """(b, k) int64 facets, (b,) int32 tags > 0 and the names {name: (tag, dimension)} of a meshio mesh."""
    blocks = [i for i, block in enumerate(data.cells) if block.type == facet_type]
    arrays = data.cell_data.get(tag_array)
    width = 3 if facet_type == "triangle" else 2
    facets, tags = np.zeros((0, width), np.int64), np.zeros(0, np.int32)
    if blocks and arrays is not None:
        facets = np.concatenate([native(data.cells[i].data) for i in blocks]).astype(np.int64)
        tags = np.concatenate([native(arrays[i]) for i in blocks]).astype(np.int32)
        facets, tags = facets[tags > 0], tags[tags > 0]
    names = {str(name): (int(value[0]), int(value[1])) for name, value in data.field_data.items()
             if np.size(value) == 2}
    return facets, tags, names


def _joined(path: Path, companion: Path, count: int, facet_type: str, found):
    """``found`` (facets, tags, names) with those of the facet file ``companion`` added."""
    data = _read_file(companion)
    if len(data.points) != count:
        raise InvalidInputError(
            f"cannot read a mesh from '{path}': its facet file '{companion.name}' has {len(data.points)} points, "
            f"the mesh {count}; the two were not written together: write the mesh again, or remove the facet file")
    facets, tags, names = _tagged_facets(data, facet_type, FACET_ARRAY)
    return np.concatenate([found[0], facets]), np.concatenate([found[1], tags]), {**found[2], **names}


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
