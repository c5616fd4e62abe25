"""bitemesh.io's mesh writers and readers (meshio): every format round trips the small meshes, VTK reads the .vtu and
.vtk files, labels become the formats' regions, the reader orients cells and picks the tetrahedra or planar
triangles, and bad mesh files and arguments are refused with the path named."""
from __future__ import annotations

import meshio
import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.io import MESH_EXTENSIONS, POINT_EXTENSIONS, read_mesh, read_points, write_mesh

from tests.builders import cube_mesh, square_mesh

# ------------------------------------------------------------------------------------------- meshes


@pytest.mark.parametrize("extension", MESH_EXTENSIONS)
@pytest.mark.parametrize("make", [cube_mesh, square_mesh])
def test_mesh_round_trip(tmp_path, capfd, extension, make):
    mesh = make()
    path = tmp_path / f"mesh{extension}"

    write_mesh(mesh, path)
    back = read_mesh(path)

    assert back.dim == mesh.dim
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    assert back.points.dtype == np.float64 and back.cells.dtype == np.int64
    for name, array in back.cell_data.items():
        assert array.dtype.isnative and len(array) == len(mesh.cells), name
    if extension in (".vtu", ".vtk", ".npz", ".h5"):   # every array as it was
        assert set(back.cell_data) == set(mesh.cell_data)
        for name, array in mesh.cell_data.items():
            np.testing.assert_array_equal(back.cell_data[name], array)
            assert back.cell_data[name].dtype == array.dtype
    elif extension == ".xdmf":  # every array, and the regions (here Label) as Region, dolfinx's cell tags
        assert set(back.cell_data) == set(mesh.cell_data) | {"Region"}
        for name, array in mesh.cell_data.items():
            np.testing.assert_array_equal(back.cell_data[name], array)
        np.testing.assert_array_equal(back.cell_data["Region"], mesh.cell_data["Label"])
    else:  # only the regions: gmsh physical tags, MEDIT references, Abaqus element sets REGION_1, REGION_2
        assert extension != ".msh" or path.read_text().startswith("$MeshFormat\n2.2 0 8\n")  # gmsh 2.2, ASCII
        assert set(back.cell_data) == {"Region"}
        np.testing.assert_array_equal(back.cell_data["Region"], mesh.cell_data["Label"])
    assert capfd.readouterr().err == ""  # neither VTK nor meshio printed anything


def test_written_vtu_and_vtk_hold_vtk_tetra_and_triangle_cells(tmp_path):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonDataModel import VTK_TETRA, VTK_TRIANGLE
    from vtkmodules.vtkIOLegacy import vtkUnstructuredGridReader
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    for mesh, cell_type in [(cube_mesh(), VTK_TETRA), (square_mesh(), VTK_TRIANGLE)]:
        for extension, Reader in [(".vtu", vtkXMLUnstructuredGridReader), (".vtk", vtkUnstructuredGridReader)]:
            path = tmp_path / f"m{mesh.dim}{extension}"
            write_mesh(mesh, path)
            reader = Reader()
            reader.SetFileName(str(path))
            reader.Update()
            grid = reader.GetOutput()
            assert grid.GetNumberOfPoints() == len(mesh.points)
            assert {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())} == {cell_type}
            np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray("Label")), mesh.cell_data["Label"])
            assert vtk_to_numpy(grid.GetPoints().GetData())[:, 2].tolist() == [0.0] * len(mesh.points) or \
                mesh.dim == 3


def test_msh_and_medit_without_labels_get_one_region(tmp_path):
    mesh = Mesh(cube_mesh().points, cube_mesh().cells)
    write_mesh(mesh, tmp_path / "plain.msh")
    assert read_mesh(tmp_path / "plain.msh").cell_data["Region"].tolist() == [1] * 6
    write_mesh(mesh.with_cell_data(Quality=np.ones(6)), tmp_path / "plain.mesh")  # a float array is not a label
    assert read_mesh(tmp_path / "plain.mesh").cell_data["Region"].tolist() == [1] * 6


def test_read_mesh_orients_cells_positively(tmp_path):
    mesh = cube_mesh()
    flipped = mesh.cells.copy()
    flipped[::2, [0, 1]] = flipped[::2, [1, 0]]
    meshio.write(tmp_path / "flipped.vtu", meshio.Mesh(mesh.points, [("tetra", flipped)]))
    assert (signed_measures(mesh.points, read_mesh(tmp_path / "flipped.vtu").cells) > 0).all()
    assert (signed_measures(mesh.points, read_mesh(tmp_path / "flipped.vtu", orient=False).cells) < 0).sum() == 3


def test_read_mesh_takes_tetra_from_mixed_files_and_planar_triangles_at_constant_z(tmp_path):
    mesh = cube_mesh()
    boundary = np.array([[0, 1, 3], [0, 3, 2]])
    meshio.write(tmp_path / "mixed.msh",
                 meshio.Mesh(mesh.points, [("triangle", boundary), ("tetra", mesh.cells)]),
                 file_format="gmsh22", binary=False)
    back = read_mesh(tmp_path / "mixed.msh")
    np.testing.assert_array_equal(back.cells, mesh.cells)

    square = square_mesh()
    lifted = np.column_stack([square.points, np.full(4, 5.0)])
    meshio.write(tmp_path / "lifted.vtu", meshio.Mesh(lifted, [("triangle", square.cells)]))
    back = read_mesh(tmp_path / "lifted.vtu")
    assert back.dim == 2
    np.testing.assert_array_equal(back.points, square.points)


def test_read_mesh_rejects_a_surface_mesh(tmp_path):
    path = tmp_path / "surface.vtu"
    meshio.write(path, meshio.Mesh(cube_mesh().points, [("triangle", np.array([[0, 1, 4], [1, 2, 7]]))]))
    with pytest.raises(InvalidInputError, match=r"no linear tetrahedra and no planar triangles \(found: triangle\)"):
        read_mesh(path)


def test_write_mesh_checks_its_input(tmp_path):
    mesh = cube_mesh()
    with pytest.raises(InvalidInputError, match="one row per cell"):
        write_mesh(mesh.with_cell_data(Bad=np.ones(2)), tmp_path / "m.vtu")
    with pytest.raises(InvalidInputError, match="must index mesh.points"):
        write_mesh(Mesh(mesh.points, mesh.cells + 5), tmp_path / "m.vtu")
    with pytest.raises(InvalidInputError, match=r"\(m, 4\) integer array"):
        write_mesh(Mesh(mesh.points, mesh.cells[:, :3]), tmp_path / "m.vtu")
    with pytest.raises(InvalidInputError, match="does not exist"):
        write_mesh(mesh, tmp_path / "missing_dir" / "m.vtu")


def test_unknown_extensions_list_the_supported_ones(tmp_path):
    path = tmp_path / "points.las"
    path.write_text("0 0 0\n")
    with pytest.raises(InvalidInputError) as caught:
        read_points(path)
    assert str(path) in str(caught.value) and all(ext in str(caught.value) for ext in POINT_EXTENSIONS)
    with pytest.raises(InvalidInputError) as caught:
        read_mesh(path.with_suffix(".exo"))
    assert all(ext in str(caught.value) for ext in MESH_EXTENSIONS)
    with pytest.raises(InvalidInputError) as caught:
        write_mesh(cube_mesh(), tmp_path / "mesh.stl")
    assert "mesh.stl" in str(caught.value) and all(ext in str(caught.value) for ext in MESH_EXTENSIONS)


@pytest.mark.parametrize("extension", MESH_EXTENSIONS)
def test_bad_mesh_files(tmp_path, vtk_silent, extension):
    missing = tmp_path / f"missing{extension}"
    with pytest.raises(InvalidInputError, match="does not exist"):
        read_mesh(missing)
    empty = tmp_path / f"empty{extension}"
    empty.write_bytes(b"")
    with pytest.raises(InvalidInputError, match="is empty"):
        read_mesh(empty)
    garbage = tmp_path / f"garbage{extension}"
    garbage.write_bytes(b"not a mesh\n\x00\x17 at all\n")
    with pytest.raises(InvalidInputError) as caught:
        read_mesh(garbage)
    assert str(garbage) in str(caught.value)
    vtk_silent()


