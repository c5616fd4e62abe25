"""XDMF 3 files with their heavy data in HDF5 (h5py), laid out as dolfinx's ``XDMFFile`` reads them.

A mesh written to ``heart.xdmf`` is four files, each XDMF file with one uniform grid named ``Grid`` (meshio's name,
so scripts written for meshio-converted meshes read these unchanged) and its arrays in the HDF5 file of the same
stem (dolfinx opens that one, whatever the ``DataItem`` says):

- ``heart.xdmf`` + ``heart.h5``: the points (``GeometryType`` ``XYZ``, ``XY`` in 2D), the cells (``TopologyType``
  ``Tetrahedron``, ``Triangle`` in 2D) and the cell arrays as ``Attribute`` elements with ``Center="Cell"``, the
  first of them ``Region`` (int32, 1 for every cell of a mesh without regions): dolfinx's cell tags;
- ``heart_facets.xdmf`` + ``heart_facets.h5`` (when the mesh has tagged facets): the same points, the facets
  (``Triangle``, ``Polyline`` in 2D) and one attribute ``SurfaceTag`` (int32): dolfinx's facet tags.

Both grids carry the tag names in an ``Information`` element named ``tag_names``: its ``Value`` is JSON
(``{"EPI": [1, 2], ...}``, name -> [tag, dimension]) and its text meshio's field-data form (meshio reads it as
``field_data``).  Reading them in DOLFINx (0.7 and later; run by tests/solvers with the PyPI wheel
dolfinx-solver-real, whose ``dolfinx_solver`` is imported first)::

    import json

    import ufl
    from dolfinx.io import XDMFFile
    from mpi4py import MPI

    with XDMFFile(MPI.COMM_WORLD, "heart.xdmf", "r") as xdmf:
        mesh = xdmf.read_mesh(name="Grid")
        cell_tags = xdmf.read_meshtags(mesh, name="Grid")    # the first attribute, Region
        names = json.loads(xdmf.read_information("tag_names", "/Xdmf/Domain/Grid"))
    mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
    with XDMFFile(MPI.COMM_WORLD, "heart_facets.xdmf", "r") as xdmf:
        facet_tags = xdmf.read_meshtags(mesh, name="Grid")   # SurfaceTag
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
    ds(names["EPI"][0])                                       # the epicardium

ParaView opens each XDMF file, and meshio reads each (``meshio.read("heart.xdmf")``).
"""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

#: XDMF topology type of each cell size (nodes per cell) bitemesh writes.
TOPOLOGY_TYPES = {4: "Tetrahedron", 3: "Triangle", 2: "Polyline"}

#: XDMF DataType of each numpy kind (bool is written as unsigned bytes).
DATA_TYPES = {"f": "Float", "i": "Int", "u": "UInt", "b": "UInt"}


def write_grid(xml_path, h5_path, h5_name: str, points: np.ndarray, cells: np.ndarray, arrays: dict,
               tag_names: dict, node_arrays: dict | None = None, unit: str = "mm") -> None:
    """Write one XDMF file holding one uniform grid named ``Grid``, its data in one HDF5 file.

    Parameters
    ----------
    xml_path, h5_path : str or Path
        Where to write the XDMF (XML) and HDF5 files (temporary names, renamed by the caller).
    h5_name : str
        The name of the HDF5 file once renamed, as the ``DataItem`` elements refer to it (no folder, no ``:``).
    points : (n, 2) or (n, 3) float64
        Node coordinates (input units).
    cells : (m, k) int64
        0-based node indices of each cell, k = 4 (tetrahedra), 3 (triangles) or 2 (edges), in VTK order.
    arrays : dict
        Name -> (m,) or (m, c) cell array, written in this order as ``Attribute`` elements with ``Center="Cell"``,
        each in the HDF5 dataset ``/CellData/<name>``.
    node_arrays : dict, optional
        Name -> (n,) or (n, c) node array, ``Center="Node"``, in ``/PointData/<name>``.
    unit : str
        The points' unit, written as the ``Unit`` attribute of the ``Geometry`` element (XDMF has no place for it;
        readers ignore it, and meshio allows one ``Information`` element only).
    tag_names : dict
        Name -> (tag, dimension); none written when empty.
    """
    import h5py

    root = ET.Element("Xdmf", Version="3.0")
    grid = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="Grid", GridType="Uniform")
    with h5py.File(h5_path, "w") as h5:
        def item(parent, dataset: str, array: np.ndarray) -> None:
            array = np.ascontiguousarray(array.astype(np.uint8) if array.dtype == bool else array)
            h5.create_dataset(dataset, data=array)
            element = ET.SubElement(parent, "DataItem", DataType=DATA_TYPES[array.dtype.kind],
                                    Precision=str(array.dtype.itemsize),
                                    Dimensions=" ".join(map(str, array.shape)), Format="HDF")
            element.text = f"{h5_name}:{dataset}"

        item(ET.SubElement(grid, "Geometry", GeometryType="XYZ"[:points.shape[1]], Unit=unit), "/Mesh/geometry",
             points)
        item(ET.SubElement(grid, "Topology", TopologyType=TOPOLOGY_TYPES[cells.shape[1]],
                           NumberOfElements=str(len(cells)), NodesPerElement=str(cells.shape[1])),
             "/Mesh/topology", cells)
        for group, center, table in (("CellData", "Cell", arrays), ("PointData", "Node", node_arrays or {})):
            for name, array in table.items():
                attribute = ET.SubElement(grid, "Attribute", Name=name, AttributeType=_attribute_type(array),
                                          Center=center)
                item(attribute, f"/{group}/{name.replace('/', '_')}",
                     array.reshape(len(array), -1) if array.ndim > 2 else array)
    if tag_names:
        information = ET.SubElement(grid, "Information", Name="tag_names",
                                    Value=json.dumps({name: list(value) for name, value in tag_names.items()}))
        field_data = ET.Element("main")
        for name, (tag, dimension) in tag_names.items():
            ET.SubElement(field_data, "map", key=name, dim=str(dimension)).text = str(tag)
        information.text = ET.tostring(field_data, encoding="unicode")
    ET.indent(root)
    ET.ElementTree(root).write(Path(xml_path), encoding="utf-8", xml_declaration=True)


def _attribute_type(array: np.ndarray) -> str:
    """Scalar for one value a cell, Vector for three, Tensor for nine, Matrix otherwise."""
    components = int(np.prod(array.shape[1:], dtype=np.int64))
    return {1: "Scalar", 3: "Vector", 9: "Tensor"}.get(components, "Matrix")
