"""Tagged meshes written where solvers read them: every format gives back the points, cells, regions, tagged facets
(as sets, with their orientation and tags) and names it holds; gmsh's own API reads the .msh physical groups, meshio
reads every file, the XDMF files are laid out as dolfinx reads them, the Abaqus surfaces use the element library's
face identifiers; the two-file formats are written atomically and never leave a stale facet file; bad tags are
refused with the parameter named."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.mesh.simplicial import Mesh, facets_of
from bitemesh.io import mesh_files, read_mesh, write_mesh

from tests.builders import cube_mesh, leftovers, positively_oriented

TAGGED_EXTENSIONS = (".msh", ".vtu", ".xdmf", ".inp", ".mesh")


def rectangle_mesh() -> Mesh:
    """[0, 2] x [0, 1] in four triangles, two a unit square."""
    points = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], dtype=float)
    return Mesh(points, positively_oriented(points, [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]]))


def tagged(mesh: Mesh, cut: int = 3) -> Mesh:
    """``mesh`` (its first ``cut`` cells region 1, the others region 2) with every boundary facet tagged by its
    cell's region (WALL_1, WALL_2) or BOTTOM (on the plane of the last coordinate = 0), and the interface facets,
    oriented out of region 1, tagged INTERFACE_1_2."""
    k = mesh.dim
    regions = np.where(np.arange(len(mesh.cells)) < cut, 1, 2).astype(np.int32)
    faces = facets_of(mesh.cells).reshape(-1, k)
    owner = np.repeat(np.arange(len(mesh.cells)), k + 1)
    _, inverse, counts = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    boundary = counts[inverse] == 1
    tags = np.where(boundary, regions[owner], 0)
    tags[boundary & (mesh.points[faces][:, :, -1].max(axis=1) == 0)] = 3
    tags[~boundary & (regions[owner] == 1) & (np.bincount(inverse, regions[owner] == 2)[inverse] == 1)] = 4
    names = {"LEFT": (1, k), "RIGHT": (2, k), "WALL_1": (1, k - 1), "WALL_2": (2, k - 1), "BOTTOM": (3, k - 1),
             "INTERFACE_1_2": (4, k - 1)}
    mesh = Mesh(mesh.points, mesh.cells, {"Quality": np.linspace(0.1, 0.9, len(mesh.cells))})
    return mesh.with_tags(faces[tags > 0], tags[tags > 0], names, regions=regions)


def cube() -> Mesh:
    return tagged(cube_mesh())


def rectangle() -> Mesh:
    return tagged(rectangle_mesh(), cut=2)


def facet_set(facets, tags) -> set:
    """The facets as {(vertices from the smallest, in the facet's cyclic order), tag}: equal for equal oriented
    facets."""
    return {(tuple(np.roll(facet, -int(np.argmin(facet))).tolist()), int(tag)) for facet, tag in zip(facets, tags)}


def test_the_fixtures_are_what_they_say():
    mesh = cube()
    assert np.bincount(mesh.facet_tags).tolist() == [0, 4, 6, 2, 2]  # 12 boundary triangles (2 on z = 0), 2 interfaces
    assert len(rectangle().facets) == 7 and sorted(rectangle().facet_tags.tolist()) == [1, 1, 2, 2, 3, 3, 4]


# ------------------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("extension", TAGGED_EXTENSIONS)
@pytest.mark.parametrize("make", [cube, rectangle])
def test_each_format_round_trips_its_tags(tmp_path, capfd, extension, make):
    mesh = make()
    path = tmp_path / f"mesh{extension}"

    write_mesh(mesh, path)
    back = read_mesh(path)

    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in mesh_files(path))
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    np.testing.assert_array_equal(back.cell_data["Region"], mesh.cell_data["Region"])
    assert back.cell_data["Region"].dtype == np.int32 and back.facet_tags.dtype == np.int32
    assert facet_set(back.facets, back.facet_tags) == facet_set(mesh.facets, mesh.facet_tags)
    assert back.tag_names == ({} if extension == ".mesh" else mesh.tag_names)  # MEDIT has no names
    assert capfd.readouterr().err == ""


def test_vtk_keeps_the_regions_but_not_the_facets(tmp_path):
    write_mesh(cube(), tmp_path / "mesh.vtk")
    back = read_mesh(tmp_path / "mesh.vtk")
    np.testing.assert_array_equal(back.cell_data["Region"], cube().cell_data["Region"])
    assert back.facets is None and [p.name for p in tmp_path.iterdir()] == ["mesh.vtk"]


@pytest.mark.parametrize("extension", TAGGED_EXTENSIONS + (".vtk",))
def test_a_mesh_without_tags_writes_one_file_and_reads_back_without_tags(tmp_path, extension):
    path = tmp_path / f"plain{extension}"
    write_mesh(Mesh(cube_mesh().points, cube_mesh().cells), path)
    back = read_mesh(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == (["plain.h5", "plain.xdmf"] if extension == ".xdmf"
                                                          else [path.name])
    assert back.facets is None and back.facet_tags is None and back.tag_names == {}
    text = path.read_text(errors="replace")
    assert "$PhysicalNames" not in text and "*SURFACE" not in text and "*ELSET" not in text


# ------------------------------------------------------------------------------------------- gmsh and meshio


@pytest.mark.parametrize("make", [cube, rectangle])
def test_gmsh_reads_the_physical_groups_with_their_names_and_elements(tmp_path, make):
    import gmsh  # the test extra installs it

    mesh = make()
    path = tmp_path / "mesh.msh"
    write_mesh(mesh, path)
    k = mesh.dim
    gmsh.initialize(["gmsh", "-v", "0"])
    try:
        gmsh.open(str(path))
        groups = {}
        for dimension, tag in gmsh.model.getPhysicalGroups():
            elements = [gmsh.model.mesh.getElements(dimension, entity)
                        for entity in gmsh.model.getEntitiesForPhysicalGroup(dimension, tag)]
            nodes = np.concatenate([node_tags[0] for _, _, node_tags in elements]).astype(np.int64) - 1
            groups[gmsh.model.getPhysicalName(dimension, tag)] = (tag, dimension, nodes.reshape(-1, dimension + 1))
    finally:
        gmsh.finalize()
    assert {name: (tag, dimension) for name, (tag, dimension, _) in groups.items()} == mesh.tag_names
    for tag, dimension, elements in groups.values():
        if dimension == k:
            np.testing.assert_array_equal(elements, mesh.cells[mesh.cell_data["Region"] == tag])
        else:
            assert facet_set(elements, [tag] * len(elements)) == \
                facet_set(mesh.facets[mesh.facet_tags == tag], mesh.facet_tags[mesh.facet_tags == tag])


def test_meshio_reads_each_file_as_solvers_and_viewers_see_it(tmp_path):
    mesh = cube()
    field_data = {name: list(value) for name, value in mesh.tag_names.items()}
    for extension in TAGGED_EXTENSIONS:
        write_mesh(mesh, tmp_path / f"m{extension}")
    msh = meshio.read(tmp_path / "m.msh")
    assert [block.type for block in msh.cells] == ["tetra", "triangle"]
    assert [a.tolist() for a in msh.cell_data["gmsh:physical"]] == [mesh.cell_data["Region"].tolist(),
                                                                    mesh.facet_tags.tolist()]
    assert {name: value.tolist() for name, value in msh.field_data.items()} == field_data
    for name in ("m.vtu", "m.xdmf"):
        volume, facets = meshio.read(tmp_path / name), meshio.read(tmp_path / name.replace("m.", "m_facets."))
        assert [block.type for block in volume.cells] == ["tetra"] and [b.type for b in facets.cells] == ["triangle"]
        assert volume.cell_data["Region"][0].tolist() == mesh.cell_data["Region"].tolist()
        np.testing.assert_array_equal(volume.cell_data["Quality"][0], mesh.cell_data["Quality"])
        assert facets.cell_data["SurfaceTag"][0].tolist() == mesh.facet_tags.tolist()
        for data in (volume, facets):
            assert {name: value.tolist() for name, value in data.field_data.items()} == field_data
    inp = meshio.read(tmp_path / "m.inp")
    assert inp.cell_sets["LEFT"][0].tolist() == [0, 1, 2] and inp.cell_sets["RIGHT"][0].tolist() == [3, 4, 5]
    assert sorted(inp.point_sets["BOTTOM"].tolist()) == sorted(set(mesh.facets[mesh.facet_tags == 3].ravel()))
    medit = meshio.read(tmp_path / "m.mesh")
    assert [a.tolist() for a in medit.cell_data["medit:ref"]] == [mesh.cell_data["Region"].tolist(),
                                                                 mesh.facet_tags.tolist()]


# ------------------------------------------------------------------------------------------- XDMF for dolfinx


def test_the_xdmf_files_are_laid_out_as_dolfinx_reads_them(tmp_path):
    import h5py

    mesh = cube()
    write_mesh(mesh, tmp_path / "heart.xdmf")
    expected = {"heart.xdmf": ("Tetrahedron", mesh.cells, "Region", mesh.cell_data["Region"]),
                "heart_facets.xdmf": ("Triangle", mesh.facets, "SurfaceTag", mesh.facet_tags)}
    for name, (topology_type, cells, tags_name, tags) in expected.items():
        root = ET.parse(tmp_path / name).getroot()
        assert root.tag == "Xdmf" and root.get("Version") == "3.0"
        grid = root.find("Domain/Grid[@Name='Grid']")  # read_mesh(name="Grid"), read_meshtags(mesh, name="Grid")
        topology, geometry = grid.find("Topology"), grid.find("Geometry")
        assert (topology.get("TopologyType"), topology.get("NumberOfElements"), topology.get("NodesPerElement")) \
            == (topology_type, str(len(cells)), str(cells.shape[1]))
        assert geometry.get("GeometryType") == "XYZ"
        attribute = grid.find("Attribute")  # read_meshtags takes the first attribute
        assert (attribute.get("Name"), attribute.get("Center")) == (tags_name, "Cell")
        assert json.loads(grid.find("Information[@Name='tag_names']").get("Value")) == \
            {name: list(value) for name, value in mesh.tag_names.items()}
        h5_name = name.replace(".xdmf", ".h5")  # dolfinx opens the .h5 of the same stem
        with h5py.File(tmp_path / h5_name, "r") as h5:
            for item, array in ((topology, cells), (geometry, mesh.points), (attribute, tags)):
                data_item = item.find("DataItem")
                file_name, dataset = data_item.text.strip().split(":")
                assert data_item.get("Format") == "HDF" and file_name == h5_name
                shape = tuple(int(n) for n in data_item.get("Dimensions").split())
                assert h5[dataset].shape == shape  # dolfinx needs the XML and HDF5 shapes equal
                np.testing.assert_array_equal(h5[dataset][()], array)
            assert h5[topology.find("DataItem").text.split(":")[1]].dtype == np.int64


def test_the_xdmf_of_a_2d_mesh_has_xy_points_and_polyline_facets(tmp_path):
    write_mesh(rectangle(), tmp_path / "m.xdmf")
    grid = ET.parse(tmp_path / "m.xdmf").getroot().find("Domain/Grid")
    assert grid.find("Geometry").get("GeometryType") == "XY" and grid.find("Topology").get("TopologyType") == \
        "Triangle"
    facets = ET.parse(tmp_path / "m_facets.xdmf").getroot().find("Domain/Grid/Topology")
    assert (facets.get("TopologyType"), facets.get("NodesPerElement")) == ("Polyline", "2")


def test_an_xdmf_file_name_with_a_colon_is_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="cannot hold ':'"):
        write_mesh(cube(), tmp_path / "a:b.xdmf")


# ------------------------------------------------------------------------------------------- Abaqus


def test_abaqus_face_identifiers_follow_the_element_library(tmp_path):
    """C3D4: S1 = nodes 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1; CPS3: S1 = 1-2, S2 = 2-3, S3 = 3-1."""
    for points, cell, faces in [
            (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float), [0, 1, 2, 3],
             {"S1": {0, 1, 2}, "S2": {0, 3, 1}, "S3": {1, 3, 2}, "S4": {2, 3, 0}}),
            (np.array([[0, 0], [1, 0], [0, 1]], float), [0, 1, 2], {"S1": {0, 1}, "S2": {1, 2}, "S3": {2, 0}})]:
        mesh = Mesh(points, np.array([cell]))
        outward = facets_of(mesh.cells)[0]
        named = {f"F{index}": (index + 1, mesh.dim - 1) for index in range(len(outward))}
        path = tmp_path / f"single{mesh.dim}.inp"
        write_mesh(mesh.with_tags(outward, np.arange(1, len(outward) + 1), named), path)
        text = path.read_text()
        for index, facet in enumerate(outward):
            face = next(face for face, nodes in faces.items() if nodes == set(facet.tolist()))
            assert f"*SURFACE, TYPE=ELEMENT, NAME=F{index}\n_F{index}_{face}, {face}\n" in text
            assert f"*ELSET, ELSET=_F{index}_{face}\n1\n" in text


def test_an_abaqus_surface_face_is_that_of_the_cell_the_facet_points_out_of(tmp_path):
    mesh = cube()
    flipped = mesh.facets.copy()
    flipped[mesh.facet_tags == 4] = flipped[mesh.facet_tags == 4, ::-1]  # out of region 2 (cells 3, 4, 5)
    for facets, cells in [(mesh.facets, {0, 1, 2}), (flipped, {3, 4, 5})]:
        write_mesh(mesh.with_tags(facets, mesh.facet_tags, mesh.tag_names), tmp_path / "m.inp")
        sets = meshio.read(tmp_path / "m.inp").cell_sets
        faces = [name for name in sets if name.startswith("_INTERFACE_1_2_")]
        assert faces and set(np.concatenate([sets[name][0] for name in faces]).tolist()) <= cells
        back = read_mesh(tmp_path / "m.inp")
        assert facet_set(back.facets, back.facet_tags) == facet_set(facets, mesh.facet_tags)


def test_an_inverted_abaqus_element_gives_its_faces_back_outward(tmp_path):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    outward = facets_of(np.array([[0, 1, 2, 3]]))[0]
    inverted = Mesh(points, np.array([[1, 0, 2, 3]]))  # negatively oriented: read_mesh turns it
    write_mesh(inverted.with_tags(outward, [1, 2, 3, 4], {}), tmp_path / "m.inp")
    back = read_mesh(tmp_path / "m.inp")
    assert back.cells.tolist() == [[0, 1, 2, 3]]
    assert facet_set(back.facets, back.facet_tags) == facet_set(outward, [1, 2, 3, 4])


def test_an_abaqus_facet_must_be_a_face(tmp_path):
    mesh = cube()
    bad = mesh.with_tags(np.array([[0, 1, 2]]), [1], {})  # (0, 1, 2) is no face of the cube's tetrahedra
    with pytest.raises(InvalidInputError, match=r"mesh.facets\[0\] = \[0, 1, 2\] is not a face of any cell"):
        write_mesh(bad, tmp_path / "bad.inp")


def test_abaqus_numbers_fit_in_20_characters(tmp_path):
    """Abaqus reads at most 20 characters a floating-point number; CalculiX stops at a longer one."""
    mesh = cube()
    write_mesh(Mesh(-np.pi * 1e5 * mesh.points, mesh.cells), tmp_path / "m.inp")
    text = (tmp_path / "m.inp").read_text()
    nodes = text[text.index("*NODE\n") + 6:text.index("*ELEMENT")].split()
    assert len(nodes) == 8 * 4 and max(len(field.strip(",")) for field in nodes) <= 20
    np.testing.assert_allclose(read_mesh(tmp_path / "m.inp").points, -np.pi * 1e5 * mesh.points, rtol=1e-12)


def test_abaqus_refuses_names_it_cannot_take(tmp_path):
    mesh = cube()
    with pytest.raises(InvalidInputError, match="'LV endo' cannot name an Abaqus set.*e.g. 'LV_endo'"):
        write_mesh(mesh.with_tags(mesh.facets, mesh.facet_tags, {"LV endo": (1, 2)}), tmp_path / "m.inp")
    with pytest.raises(InvalidInputError, match="'EPI' and 'epi' are one name to Abaqus"):
        write_mesh(mesh.with_tags(mesh.facets, mesh.facet_tags, {"EPI": (1, 2), "epi": (2, 2)}), tmp_path / "m.inp")
    assert leftovers(tmp_path) == [] and not (tmp_path / "m.inp").exists()


# ------------------------------------------------------------------------------------------- two files, atomically


def test_an_interrupted_write_of_a_two_file_format_leaves_the_previous_files(monkeypatch, tmp_path):
    from bitemesh.io import meshes

    for extension, module, name in [(".vtu", meshio, "write"), (".xdmf", meshes, "write_grid")]:
        path = tmp_path / f"m{extension}"
        write_mesh(cube(), path)
        before = {file: file.read_bytes() for file in mesh_files(path)}
        real, calls = getattr(module, name), []

        def interrupted(*args, real=real, calls=calls, **options):
            calls.append(1)
            if len(calls) == 2:  # the facet file, half written
                raise KeyboardInterrupt
            real(*args, **options)

        monkeypatch.setattr(module, name, interrupted)
        bigger = tagged(Mesh(cube_mesh().points * 2, cube_mesh().cells))
        with pytest.raises(KeyboardInterrupt):
            write_mesh(bigger, path)
        monkeypatch.undo()
        assert calls == [1, 1]
        assert {file: file.read_bytes() for file in mesh_files(path)} == before
        assert leftovers(tmp_path) == []


def test_a_mesh_without_facets_removes_the_facet_file_of_an_earlier_write(tmp_path):
    for extension in (".vtu", ".xdmf"):
        path = tmp_path / f"m{extension}"
        write_mesh(cube(), path)
        assert all(file.exists() for file in mesh_files(path))
        write_mesh(Mesh(cube_mesh().points, cube_mesh().cells), path)
        assert [file.exists() for file in mesh_files(path)] == [True, True, False, False][:len(mesh_files(path))] \
            if extension == ".xdmf" else [True, False]
        assert read_mesh(path).facets is None


def test_a_facet_file_that_does_not_fit_its_mesh_is_refused(tmp_path):
    write_mesh(cube(), tmp_path / "m.vtu")
    small = Mesh(cube_mesh().points[:4], np.array([[0, 1, 2, 3]]))
    write_mesh(small.with_tags(facets_of(small.cells)[0], [1, 1, 1, 1], {}), tmp_path / "other.vtu")
    Path(tmp_path / "other_facets.vtu").replace(tmp_path / "m_facets.vtu")
    with pytest.raises(InvalidInputError, match="facet file 'm_facets.vtu' has 4 points, the mesh 8"):
        read_mesh(tmp_path / "m.vtu")


# ------------------------------------------------------------------------------------------- bad tags


@pytest.mark.parametrize("facets, tags, names, message", [
    (np.array([[0, 1]]), [1], {}, r"mesh.facets must be an \(b, 3\) integer array"),
    (np.array([[0, 1, 9]]), [1], {}, r"mesh.facets must index mesh.points \(0..7\)"),
    (np.array([[0, 1, 3]]), [0], {}, "mesh.facet_tags must be .* integers > 0"),
    (np.array([[0, 1, 3]]), [1, 2], {}, r"mesh.facet_tags must be \(1,\) integers"),
    (np.array([[0, 1, 3]]), [1], {"TOP": (1, 1)}, r"mesh.tag_names\['TOP'\] = \(1, 1\).*dimension 3 for a region"),
    (np.array([[0, 1, 3]]), [1], {'"Q"': (1, 2)}, "without quotes"),
])
def test_bad_tags_are_refused_with_the_parameter_named(tmp_path, facets, tags, names, message):
    mesh = Mesh(cube_mesh().points, cube_mesh().cells).with_tags(facets, tags, names)
    with pytest.raises(InvalidInputError, match=message):
        write_mesh(mesh, tmp_path / "m.msh")
    assert list(tmp_path.iterdir()) == []


def test_vtk_reads_the_names_of_the_vtu_files_and_the_xdmf_files(tmp_path):
    """What ParaView opens: the .vtu field data (VTK's XML reader), the XDMF grids (VTK's XDMF reader)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXdmf2 import vtkXdmfReader
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    mesh = cube()
    write_mesh(mesh, tmp_path / "m.vtu")
    write_mesh(mesh, tmp_path / "m.xdmf")
    for name, Reader, cells, array, values in [
            ("m.vtu", vtkXMLUnstructuredGridReader, 6, "Region", mesh.cell_data["Region"]),
            ("m_facets.vtu", vtkXMLUnstructuredGridReader, 14, "SurfaceTag", mesh.facet_tags),
            ("m.xdmf", vtkXdmfReader, 6, "Region", mesh.cell_data["Region"]),
            ("m_facets.xdmf", vtkXdmfReader, 14, "SurfaceTag", mesh.facet_tags)]:
        reader = Reader()
        reader.SetFileName(str(tmp_path / name))
        reader.Update()
        grid = reader.GetOutputDataObject(0)
        assert grid.GetNumberOfCells() == cells, name
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray(array)), values)
        if name.endswith(".vtu"):
            field = grid.GetFieldData()
            assert {field.GetArrayName(i): tuple(vtk_to_numpy(field.GetArray(i)).tolist())
                    for i in range(field.GetNumberOfArrays())} == mesh.tag_names
