"""The folder cardiac-geometries and fenicsx-pulse read (``cardiac_geometries.geometry.Geometry.from_folder``).

A mesh written to ``heart`` (an output without an extension) is the folder ``heart/``:

- ``mesh.xdmf`` + ``mesh.h5``: the grids as dolfinx's ``XDMFFile`` writes them and cardiac-geometries reads them:
  ``Mesh`` (the points and the cells), ``Cell tags`` (the cells with their Region), ``Facet tags`` (the tagged
  facets with their tag) and, for a heart, ``Edge tags`` (its base rings) and ``Vertex tags`` (its apex points:
  :mod:`bitemesh.core.fem.landmarks`), the tag grids on the mesh's geometry;
- ``markers.json``: ``{name: [tag, dimension]}``, the tag names; a biventricular heart's LV_ENDO and RV_ENDO are
  also given as ``LV`` and ``RV``, the names of cardiac-geometries' biventricular ellipsoid, by which its
  ``transform_markers`` hands them to ldrb;
- ``info.json``: the generator and the unit of the coordinates (``"unit": "mm"``, ``--unit``; pulse assumes
  metres unless told: ``HeartGeometry.from_cardiac_geometries(..., metadata)`` with the mesh scaled by 1e-3).

The fibres are not in the folder: cardiac-geometries reads them only from an ADIOS2 checkpoint
(``microstructure.bp``), which needs the adios2 Python module built with MPI; write ``.xdmf`` for them.
"""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError
from ..core.fem.landmarks import landmarks
from ..core.mesh.topology import first_rows

#: the files of a folder, in the order :func:`write_folder` fills the temporary paths.
FOLDER_FILES = ("mesh.xdmf", "mesh.h5", "markers.json", "info.json")
#: the extra names a biventricular heart's surfaces get in markers.json (cardiac-geometries' BiV ellipsoid's).
ALIASES = {"LV_ENDO": "LV", "RV_ENDO": "RV"}
#: the XDMF topology of entities of k + 1 nodes, as dolfinx writes them.
TOPOLOGY_TYPES = {4: "Tetrahedron", 3: "Triangle", 2: "PolyLine", 1: "PolyVertex"}
#: the grids of the tags (cardiac-geometries' names) by the entities' dimension below the cells'.
TAG_GRIDS = ("Cell tags", "Facet tags", "Edge tags", "Vertex tags")


def folder_files(path) -> list:
    return [Path(path) / name for name in FOLDER_FILES]


def markers(tag_names: dict) -> dict:
    """markers.json's content: the names, and the aliases of :data:`ALIASES` where the alias is not a name."""
    found = {name: [int(tag), int(dimension)] for name, (tag, dimension) in tag_names.items()}
    for name, alias in ALIASES.items():
        if name in found and alias not in found:
            found[alias] = found[name]
    return found


def write_folder(mesh, regions, temporaries: list, files: list) -> None:
    """Write ``mesh`` (tetrahedra, mm) to the temporary paths of ``files`` (:func:`folder_files`)."""
    import h5py

    if mesh.dim != 3:
        raise InvalidInputError("a cardiac-geometries folder holds a tetrahedral mesh; this mesh is 2D: write .xdmf")
    try:
        edges, edge_tags, vertices, vertex_tags, landmark_names = landmarks(mesh)
    except InvalidInputError:   # not a heart: no landmarks
        edges, edge_tags, vertices, vertex_tags, landmark_names = (np.zeros((0, 2), np.int64), np.zeros(0, np.int32),
                                                                   np.zeros(0, np.int64), np.zeros(0, np.int32), {})
    xml_path, h5_path, markers_path, info_path = temporaries
    h5_name = files[1].name
    regions = np.ones(len(mesh.cells), np.int32) if regions is None else np.asarray(regions, np.int32)
    root = ET.Element("Xdmf", Version="3.0", attrib={"xmlns:xi": "https://www.w3.org/2001/XInclude"})
    domain = ET.SubElement(root, "Domain")
    with h5py.File(h5_path, "w") as h5:
        def item(parent, dataset: str, array: np.ndarray, **kind) -> None:
            h5.create_dataset(dataset, data=array)
            element = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, array.shape)), Format="HDF",
                                    **kind)
            element.text = f"{h5_name}:{dataset}"

        grid = ET.SubElement(domain, "Grid", Name="Mesh", GridType="Uniform")
        topology(grid, mesh.cells)
        item(grid[-1], "/Mesh/Mesh/topology", mesh.cells.astype(np.int64), NumberType="Int")
        item(ET.SubElement(grid, "Geometry", GeometryType="XYZ"), "/Mesh/Mesh/geometry", mesh.points)
        tagged = (("Cell tags", mesh.cells, regions), ("Facet tags", mesh.facets, mesh.facet_tags),
                  ("Edge tags", edges, edge_tags), ("Vertex tags", vertices.reshape(-1, 1), vertex_tags))
        for name, entities, values in tagged:
            if name != "Cell tags" and not len(entities):
                continue
            grid = ET.SubElement(domain, "Grid", Name=name, GridType="Uniform")
            ET.SubElement(grid, "xi:include", xpointer="xpointer(/Xdmf/Domain/Grid[@Name='Mesh']/Geometry)")
            topology(grid, entities)
            item(grid[-1], f"/MeshTags/{name}/topology", entities.astype(np.int64), NumberType="Int")
            attribute = ET.SubElement(grid, "Attribute", Name=name, AttributeType="Scalar", Center="Cell")
            item(attribute, f"/MeshTags/{name}/Values", values.astype(np.int32).reshape(-1, 1))
    ET.indent(root)
    ET.ElementTree(root).write(xml_path, encoding="utf-8", xml_declaration=True)
    Path(markers_path).write_text(json.dumps(markers({**mesh.tag_names, **landmark_names}), indent=4))
    Path(info_path).write_text(json.dumps({"generator": "bitemesh", "unit": mesh.unit}, indent=4))


def topology(grid, entities: np.ndarray) -> None:
    ET.SubElement(grid, "Topology", TopologyType=TOPOLOGY_TYPES[entities.shape[1]],
                  NumberOfElements=str(len(entities)), NodesPerElement=str(entities.shape[1]))


def read_folder(path: Path):
    """(points, cells, cell_data, facets, facet_tags, tag_names, unit) of a folder's mesh.xdmf (as this module or
    dolfinx writes it: the grids Mesh, Cell tags, Facet tags; the edge and vertex tags left out), markers.json (the
    aliases of :data:`ALIASES` and the names of edges and vertices left out) and info.json (the unit, else mm)."""
    import h5py

    xml_path = path / "mesh.xdmf"
    if not xml_path.is_file():
        raise InvalidInputError(f"cannot read a mesh from the folder '{path}': it has no mesh.xdmf (a "
                                "cardiac-geometries folder holds mesh.xdmf, mesh.h5 and markers.json)")
    grids = {grid.get("Name"): grid for grid in ET.parse(xml_path).getroot().iter("Grid")}
    if "Mesh" not in grids:
        raise InvalidInputError(f"cannot read a mesh from '{xml_path}': it has no grid named 'Mesh'")

    def data(element) -> np.ndarray:
        file, dataset = element.find("DataItem").text.strip().split(":", 1)
        with h5py.File(path / file, "r") as h5:
            return np.asarray(h5[dataset])

    points = data(grids["Mesh"].find("Geometry")).astype(np.float64)
    cells = data(grids["Mesh"].find("Topology")).astype(np.int64)
    tags = {name: (data(grids[name].find("Topology")).astype(np.int64),
                   data(grids[name].find("Attribute")).reshape(-1).astype(np.int32))
            for name in TAG_GRIDS[:2] if name in grids}   # a Mesh holds no edge or vertex tags
    cell_data = {}
    if "Cell tags" in tags:
        regions = np.zeros(len(cells), np.int32)
        where = first_rows(np.sort(cells, axis=1), np.sort(tags["Cell tags"][0], axis=1))
        regions[where[where >= 0]] = tags["Cell tags"][1][where >= 0]
        cell_data["Region"] = regions
    facets, facet_tags = tags.get("Facet tags", (None, None))
    markers_path = path / "markers.json"
    names = json.loads(markers_path.read_text()) if markers_path.is_file() else {}
    tag_names = {name: (int(tag), int(dimension)) for name, (tag, dimension) in names.items()
                 if int(dimension) >= 2 and not (name in ALIASES.values() and any(
                     original in names for original, alias in ALIASES.items() if alias == name))}
    info = path / "info.json"
    unit = json.loads(info.read_text()).get("unit", "mm") if info.is_file() else "mm"
    return points, cells, cell_data, facets, facet_tags, tag_names, unit
