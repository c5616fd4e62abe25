"""Tetrahedral (and 2D triangle) meshes with their tags, to and from the files solvers read; every write is atomic.

What each format holds of a :class:`~bitemesh.core.mesh.simplicial.Mesh` ``m`` (regions: ``cell_data["Region"]``; the
tagged
facets; the tag names; in 2D the cells are triangles and the facets edges):

- ``.msh``, gmsh 2.2 ASCII: the cells with physical and elementary tag = region (1 without regions), the facets
  as triangles (lines in 2D) with physical and elementary tag = facet tag, ``$PhysicalNames`` from the names
  (volume groups of dimension 3, surface groups of dimension 2); no other cell array.
- ``.vtu``: ``m.vtu`` the cells with every cell array, and ``m_facets.vtu`` (when there are facets) the same points
  and the facets with the cell array ``SurfaceTag``; both with the names as field data (name -> [tag, dimension]).
- ``.xdmf``: ``m.xdmf`` + ``m.h5``, ``m_facets.xdmf`` + ``m_facets.h5``, as dolfinx reads them (:mod:`.xdmf`).
- ``.inp``, Abaqus: the nodes, ``C3D4`` (``CPS3``) elements, an element set per region, an element-based surface
  and a node set per facet tag (:mod:`.abaqus`); no cell array.
- ``.mesh``, MEDIT ASCII: the cells with reference = region (1 without regions), the facets with reference = facet
  tag.  The format has no place for names: they are not written, and the file reads back without them.
- ``.vtk``, legacy VTK 4.2 binary: the cells with every cell array; no facets and no names (use ``.vtu``).
- no extension: the folder cardiac-geometries and fenicsx-pulse read, ``m/mesh.xdmf`` + ``mesh.h5`` (the grids
  Mesh, Cell tags, Facet tags), ``m/markers.json``, ``m/info.json`` (:mod:`.folders`); no cell array.
- ``.pts``, openCARP (``carp_txt``): ``m.pts`` in micrometres (the mesh in mm), ``m.elem`` with the regions,
  ``m.lon`` with Fibre and Sheet, ``m_NAME.surf`` and ``m_NAME.vtx`` a surface, ``m_tags.json`` (:mod:`.opencarp`).
- ``.npz`` (numpy's zip of arrays) and ``.h5`` (HDF5), for meshes of any dimension k = 2..5 (the only ones for
  k > 3: VTK, gmsh, XDMF and the solvers' formats have no 4-simplex): ``points`` (n, k), ``cells`` (m, k + 1),
  ``facets``, ``facet_tags``, ``cell_data/NAME`` and ``point_data/NAME`` for each array (in HDF5 the groups
  ``cell_data`` and ``point_data``), ``tag_names`` (JSON) and ``unit`` (in HDF5 the file's attributes).

Reading (:mod:`.mesh_reading`) joins what writing split (``m.vtu`` with ``m_facets.vtu``) and gives the regions back
as ``Region``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..core.errors import InvalidInputError, check_points
from ..core.mesh.simplicial import MAX_DIMENSION, Mesh
from .abaqus import abaqus_sets
from .folders import folder_files, write_folder
from .opencarp import MICROMETRES, opencarp_files, write_opencarp
from .files import atomic_outputs, meshio_warnings, native, supported
from .xdmf import write_grid

MESH_EXTENSIONS = (".vtu", ".vtk", ".msh", ".inp", ".mesh", ".xdmf", ".pts", ".npz", ".h5")

#: The formats that hold a mesh of any dimension (the others: 2-D and 3-D).
ANY_DIMENSION = (".npz", ".h5")
#: the mesh formats that keep no cell arrays but the regions (openCARP: the fibres only): the fibres (or any cell
#: vector) cannot go there.
NO_CELL_ARRAYS = (".msh", ".inp", ".mesh")

#: meshio file format written for each extension meshio writes (``.msh`` is gmsh 2.2 ASCII, ``.vtk`` legacy 4.2
#: binary); ``.xdmf`` is written by :mod:`.xdmf` and read by meshio.
MESHIO_FORMATS = {".vtu": "vtu", ".vtk": "vtk42", ".msh": "gmsh22", ".inp": "abaqus", ".mesh": "medit"}

#: Integer cell arrays taken, in this order, as region labels (gmsh physical tag, medit reference) on writing.
REGION_ARRAYS = ("Region", "Label", "gmsh:physical", "medit:ref")

#: The facet tags' cell array in ``.vtu`` and ``.xdmf`` facet files.
FACET_ARRAY = "SurfaceTag"

#: The cell array that holds the regions and the facet tags in the files of a format that has one for both.
TAG_ARRAYS = {".msh": "gmsh:physical", ".mesh": "medit:ref"}


def mesh_files(path, with_facets: bool = True) -> list:
    """The files :func:`write_mesh` writes for ``path``, ``path`` first: ``m.xdmf`` adds ``m.h5``; with facets,
    ``m.vtu`` adds ``m_facets.vtu`` and ``m.xdmf`` adds ``m_facets.xdmf`` and ``m_facets.h5``; ``m.pts`` adds
    ``m.elem``, ``m.lon`` and ``m_tags.json`` (and the surfaces: :func:`~.opencarp.opencarp_files`)."""
    path = through_link(path)
    suffix = path.suffix.lower()
    if suffix == ".pts":   # and a .surf and .vtx file a tagged surface, named by the mesh's tags
        return opencarp_files(path, {}, 3)
    if suffix == "":
        return folder_files(path)
    files = [path, path.with_suffix(".h5")] if suffix == ".xdmf" else [path]
    if with_facets and suffix in (".vtu", ".xdmf"):
        files += [facet_file(file) for file in files]
    return files


def facet_file(path: Path) -> Path:
    """``m_facets.vtu`` for ``m.vtu`` (beside the file a symbolic link ``m.vtu`` points to)."""
    path = through_link(path)
    return path.with_name(f"{path.stem}_facets{path.suffix}")


def through_link(path) -> Path:
    """``path``, or the file it points to when it is a symbolic link: a mesh written through a link has its
    companions beside its target, named after it, so that the target and the link read the same."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def write_mesh(mesh: Mesh, path) -> None:
    """Write a triangle (2D) or tetrahedral (3D) mesh with its tags, the format chosen by the extension of ``path``.

    ``.vtu`` (VTK XML, binary, zlib), ``.vtk`` (legacy VTK 4.2, binary), ``.msh`` (gmsh 2.2 ASCII), ``.inp``
    (Abaqus), ``.mesh`` (MEDIT ASCII) through meshio, ``.xdmf`` (XDMF 3 with HDF5) through h5py; what each holds:
    this module's docstring.  VTK and gmsh get z = 0 for a 2D mesh.  Region labels are the first 1-D integer
    array named in :data:`REGION_ARRAYS`.

    Parameters
    ----------
    mesh : Mesh
        points (n, k) float64 with k = 2 or 3, cells (m, k + 1) int, cell_data name -> (m, ...) arrays, and
        optionally facets (b, k) int (faces of the cells), facet_tags (b,) int > 0 and tag_names name -> (tag,
        dimension) with dimension k (a region) or k - 1 (a facet tag).
    path : str or Path
        The output file; its directory must exist.  Every file of the output (:func:`mesh_files`) is written to a
        temporary file beside it, and the temporary files are renamed onto them once all are written whole: a
        failed or interrupted write leaves the previous files as they were (or none).  A facet file left by an
        earlier write is removed when this mesh has no facets.

    Raises
    ------
    InvalidInputError
        Unknown extension, a missing directory, or a mesh whose arrays or tags are not as above.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_EXTENSIONS + ("",):
        raise InvalidInputError(
            f"cannot write a mesh to '{path}': unknown extension {path.suffix or '(none)'!r}; "
            f"supported extensions: {supported(MESH_EXTENSIONS)}")
    if suffix == ".xdmf" and ":" in path.name:
        raise InvalidInputError(f"cannot write a mesh to '{path}': an XDMF file names its HDF5 file as 'file:path', "
                                "so the file name cannot hold ':'; choose another name")
    mesh, regions = _checked_mesh(mesh, any_dimension=suffix in ANY_DIMENSION)
    if suffix in ANY_DIMENSION:
        with atomic_outputs([path]) as temporaries:
            _write_arrays(mesh, temporaries[0], suffix)
        return
    if suffix == "":
        if path.exists() and not path.is_dir():
            raise InvalidInputError(f"cannot write a cardiac-geometries folder to '{path}': it is a file; give "
                                    "another name, or an extension such as .vtu")
        if not path.parent.is_dir():
            raise InvalidInputError(f"cannot write a mesh to '{path}': the directory '{path.parent}' does not exist")
        path.mkdir(exist_ok=True)
        with atomic_outputs(folder_files(path), "a cardiac-geometries folder") as temporaries:
            write_folder(mesh, regions, temporaries, folder_files(path))
        return
    if suffix == ".pts":
        files = opencarp_files(path, mesh.tag_names, mesh.dim)
        with atomic_outputs(files) as temporaries:
            write_opencarp(mesh, regions, temporaries, files)
        return
    files = mesh_files(path, with_facets=len(mesh.facets) > 0)
    writer = _write_xdmf if suffix == ".xdmf" else _write_with_meshio
    with atomic_outputs(files, stale=mesh_files(path)[len(files):]) as temporaries, meshio_warnings():
        writer(mesh, regions, suffix, temporaries, files)


def write_time_series(path, meshes) -> None:
    """A ParaView time series: each of ``meshes`` as STEM_NNN.vtu beside the .pvd ``path`` (NNN its number, also its
    time), then ``path`` listing them, last, so that a series on disk is whole; each file written atomically."""
    path = Path(path)
    names = [f"{path.stem}_{number:03d}.vtu" for number in range(len(meshes))]
    for mesh, name in zip(meshes, names):
        write_mesh(mesh, path.with_name(name))
    entries = "\n".join(f'    <DataSet timestep="{number}" part="0" file={quoteattr(name)}/>'
                        for number, name in enumerate(names))
    with atomic_outputs([path], "a time series") as (temporary,):
        temporary.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                             f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n")


def _write_with_meshio(mesh: Mesh, regions, suffix: str, temporaries: list, files: list) -> None:
    import meshio

    cell_type, facet_type = ("tetra", "triangle") if mesh.dim == 3 else ("triangle", "line")
    points = mesh.points
    if mesh.dim == 2 and suffix in (".vtu", ".vtk", ".msh"):
        points = np.column_stack([points, np.zeros(len(points))])
    names = {name: np.array(value) for name, value in mesh.tag_names.items()}
    tags = regions if regions is not None else np.ones(len(mesh.cells), dtype=np.int32)
    blocks = [(cell_type, mesh.cells)] + ([(facet_type, mesh.facets)] if len(mesh.facets) else [])
    pair = [tags, mesh.facet_tags][:len(blocks)]
    options, appended = {}, ""
    if suffix == ".msh":
        # Only the tags: meshio 5.3 writes ASCII $ElementData values as numpy reprs ("np.int32(1)") under numpy 2,
        # which no reader (meshio included) can parse.
        contents = meshio.Mesh(points, blocks, cell_data={"gmsh:physical": pair, "gmsh:geometrical": pair},
                               field_data=names)
        options = {"binary": False}
    elif suffix == ".mesh":
        contents = meshio.Mesh(points, blocks, cell_data={"medit:ref": pair})
    elif suffix == ".inp":
        cell_sets, point_sets, appended = abaqus_sets(mesh.cells, regions, mesh.facets, mesh.facet_tags,
                                                      mesh.tag_names)
        appended = f"** the coordinates' unit: {mesh.unit}\n" + appended
        contents = meshio.Mesh(points, blocks[:1], cell_sets=cell_sets, point_sets=point_sets)
        options = {"float_fmt": ".12e"}  # Abaqus (and CalculiX) read at most 20 characters a number
    else:
        data = {name: [array.astype(np.uint8) if array.dtype == bool else array]
                for name, array in mesh.cell_data.items()}
        contents = meshio.Mesh(points, blocks[:1], cell_data=data, point_data=dict(mesh.point_data))
    meshio.write(temporaries[0], contents, file_format=MESHIO_FORMATS[suffix], **options)
    if appended:
        with open(temporaries[0], "a", encoding="utf-8") as stream:
            stream.write(appended)
    if suffix == ".vtu":
        _add_field_data(temporaries[0], mesh.tag_names)
    if len(files) > 1:  # the .vtu facet file
        meshio.write(temporaries[1], meshio.Mesh(points, blocks[1:], cell_data={FACET_ARRAY: [mesh.facet_tags]}),
                     file_format="vtu")
        _add_field_data(temporaries[1], mesh.tag_names)


def _add_field_data(path: Path, tag_names: dict) -> None:
    """Put the names into the .vtu that meshio wrote at ``path``, as VTK field data (one Int32 array [tag,
    dimension] a name): meshio 5.3 writes no field data to .vtu, but its reader, VTK and ParaView read it."""
    if not tag_names:
        return
    arrays = "".join(f'<DataArray type="Int32" Name={quoteattr(name)} NumberOfTuples="2" format="ascii">'
                     f"{tag} {dimension}</DataArray>\n" for name, (tag, dimension) in tag_names.items())
    data = Path(path).read_bytes()
    at = data.index(b"<UnstructuredGrid>") + len(b"<UnstructuredGrid>")
    Path(path).write_bytes(data[:at] + f"\n<FieldData>\n{arrays}</FieldData>".encode() + data[at:])


def _write_xdmf(mesh: Mesh, regions, suffix: str, temporaries: list, files: list) -> None:
    regions = regions if regions is not None else np.ones(len(mesh.cells), dtype=np.int32)
    arrays = {"Region": regions, **{name: array for name, array in mesh.cell_data.items() if name != "Region"}}
    write_grid(temporaries[0], temporaries[1], files[1].name, mesh.points, mesh.cells, arrays, mesh.tag_names,
               mesh.point_data, mesh.unit)
    if len(files) > 2:
        write_grid(temporaries[2], temporaries[3], files[3].name, mesh.points, mesh.facets,
                   {FACET_ARRAY: mesh.facet_tags}, mesh.tag_names, unit=mesh.unit)


def _write_arrays(mesh: Mesh, path: Path, suffix: str) -> None:
    """``mesh`` (checked) as the arrays of a ``.npz`` or ``.h5`` file (see the module docstring)."""
    arrays = {"points": mesh.points, "cells": mesh.cells, "facets": mesh.facets, "facet_tags": mesh.facet_tags}
    arrays.update({f"cell_data/{name}": array for name, array in mesh.cell_data.items()})
    arrays.update({f"point_data/{name}": array for name, array in mesh.point_data.items()})
    texts = {"tag_names": json.dumps({name: list(value) for name, value in mesh.tag_names.items()}),
             "unit": mesh.unit}
    if suffix == ".npz":
        with open(path, "wb") as stream:
            np.savez_compressed(stream, **arrays, **{name: np.array(text) for name, text in texts.items()})
        return
    import h5py
    with h5py.File(path, "w") as h5:
        for name, array in arrays.items():
            h5.create_dataset(name, data=np.ascontiguousarray(array), compression="gzip")
        h5.attrs.update(texts)


def check_holds(dimension: int, suffix: str, where: str = "") -> None:
    """Refuse a ``dimension``-D mesh for a file ending in ``suffix`` (``where`` names the file) when that format
    holds 2-D and 3-D cells only (all but :data:`ANY_DIMENSION`)."""
    if dimension > 3 and suffix not in ANY_DIMENSION:
        raise InvalidInputError(f"{where}a {dimension}-D mesh can be written to .npz or .h5 only (VTK, gmsh, XDMF, "
                                "Abaqus, MEDIT and openCARP hold 2-D and 3-D cells); give a path ending in .npz or "
                                ".h5, or write its 3-D sections (slice_mesh)")


def _checked_mesh(mesh, any_dimension: bool = False):
    """The mesh with checked, normalised arrays (facets (0, k) when it has none) and its (m,) int32 regions or
    None; points of 2 or 3 dimensions, or up to :data:`MAX_DIMENSION` with ``any_dimension`` (``.npz``, ``.h5``)."""
    if not all(hasattr(mesh, name) for name in ("points", "cells", "cell_data")):
        raise InvalidInputError(f"mesh must be a bitemesh Mesh (points, cells, cell_data), got {type(mesh).__name__}")
    dimension = np.shape(mesh.points)[-1] if np.ndim(mesh.points) == 2 else 3
    if not any_dimension and dimension <= MAX_DIMENSION:
        check_holds(dimension, "")
    points = check_points(mesh.points, "mesh.points", dims=range(2, MAX_DIMENSION + 1) if any_dimension else (2, 3))
    dim = points.shape[1]
    cells = _checked_indices(mesh.cells, "mesh.cells", "m", dim + 1, f"cells for {dim}D points", len(points))
    cell_data = {}
    for name, array in (mesh.cell_data or {}).items():
        array = np.asarray(array)
        if array.ndim == 0 or len(array) != len(cells):
            raise InvalidInputError(
                f"mesh.cell_data[{name!r}] must have one row per cell ({len(cells)}), got shape {array.shape}")
        cell_data[str(name)] = native(array)
    facets, tags = getattr(mesh, "facets", None), getattr(mesh, "facet_tags", None)
    if facets is None:
        facets, tags = np.zeros((0, dim), np.int64), np.zeros(0, np.int32)
    else:
        facets = _checked_indices(facets, "mesh.facets", "b", dim, f"facets for {dim}D points", len(points))
        tags = np.asarray(tags if tags is not None else np.zeros(0))
        if tags.shape != (len(facets),) or (tags.size and tags.dtype.kind not in "iu") or (tags <= 0).any():
            raise InvalidInputError(
                f"mesh.facet_tags must be ({len(facets)},) integers > 0, one a facet (0 means 'no tag' to gmsh and "
                f"MEDIT), got shape {tags.shape} of {tags.dtype}" + (f", min {tags.min()}" if tags.size else "")
                + "; Mesh.with_tags sets facets and tags together")
    names = {}
    for name, value in (getattr(mesh, "tag_names", None) or {}).items():
        try:
            tag, dimension = (int(number) for number in value)
        except (TypeError, ValueError):
            tag, dimension = 0, -1
        if not isinstance(name, str) or not name or set(name) & set('"\n\r\t') or tag <= 0 or \
                dimension not in (dim, dim - 1):
            raise InvalidInputError(
                f"mesh.tag_names[{name!r}] = {value!r}: a name must be a non-empty string without quotes or line "
                f"breaks, mapped to (tag > 0, dimension {dim} for a region or {dim - 1} for a facet tag)")
        names[name] = (tag, dimension)
    point_data = {}
    for name, array in (getattr(mesh, "point_data", None) or {}).items():
        array = np.asarray(array)
        if array.ndim == 0 or len(array) != len(points):
            raise InvalidInputError(
                f"mesh.point_data[{name!r}] must have one row per node ({len(points)}), got shape {array.shape}")
        point_data[str(name)] = native(array)
    unit = getattr(mesh, "unit", "mm")
    if unit not in MICROMETRES:
        raise InvalidInputError(f"mesh.unit must be one of {', '.join(MICROMETRES)}, got {unit!r}")
    return (Mesh(points, cells, cell_data, facets, tags.astype(np.int32), names, point_data, unit),
            _region_labels(cell_data))


def _checked_indices(array, name: str, rows: str, width: int, what: str, count: int) -> np.ndarray:
    """``array`` as a (rows, width) int64 array of indices into ``count`` points."""
    array = np.asarray(array)
    if array.ndim != 2 or array.shape[1] != width or (array.size and array.dtype.kind not in "iu"):
        raise InvalidInputError(f"{name} must be an ({rows}, {width}) integer array ({what}), got shape "
                                f"{array.shape} of {array.dtype}")
    array = array.astype(np.int64)
    if array.size and (array.min() < 0 or array.max() >= count):
        raise InvalidInputError(f"{name} must index mesh.points (0..{count - 1}), got values in "
                                f"[{array.min()}, {array.max()}]")
    return array


def _region_labels(cell_data):
    """(m,) int32 region labels from the first integer array in :data:`REGION_ARRAYS`, or None."""
    for name in REGION_ARRAYS:
        array = cell_data.get(name)
        if array is not None and array.ndim == 1 and array.dtype.kind in "iub":
            return array.astype(np.int32)
    return None
