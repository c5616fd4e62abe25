"""bitemesh.io's point readers: text tables (columns, headers, comments, bad rows) and VTK formats (surfaces with
outward unit normals, point clouds, unstructured grids, legacy files), and the errors of unreadable point files."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import bitemesh
import meshio
import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.io import POINT_EXTENSIONS, read_points, write_mesh

from tests.builders import cube_mesh, vtk_sphere

SPHERE_POINTS = 16 * 14 + 2  # vtkSphereSource with theta resolution 16, phi resolution 16
RADIUS = 2.0


def sphere(**options):
    """The sphere of radius 2 the VTK point files hold (vtkSphereSource, resolution 16 x 16)."""
    return vtk_sphere(RADIUS, **options)


# ------------------------------------------------------------------------------------------- text points


@pytest.mark.parametrize("extension", [".xyz", ".txt", ".csv"])
@pytest.mark.parametrize("separator", [" ", ",", "\t"])
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("with_normals", [False, True])
@pytest.mark.parametrize("header", [False, True])
def test_text_points_round_trip(tmp_path, extension, separator, dim, with_normals, header):
    rng = np.random.default_rng(7)
    points = rng.uniform(-5, 5, (12, dim))
    normals = rng.normal(size=(12, dim))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    table = np.hstack([points, normals]) if with_normals else points
    lines = [separator.join(repr(float(v)) for v in row) for row in table]
    if header:
        names = ["x", "y", "z"][:dim] + (["nx", "ny", "nz"][:dim] if with_normals else [])
        lines.insert(0, separator.join(names))
    path = tmp_path / f"cloud{extension}"
    path.write_text("\n".join(lines) + "\n")

    read, read_normals = read_points(path)

    assert read.shape == (12, dim) and read.dtype == np.float64
    np.testing.assert_array_equal(read, points)
    if with_normals:
        np.testing.assert_allclose(read_normals, normals, rtol=1e-12)
    else:
        assert read_normals is None


def test_text_points_comments_blank_lines_and_unnormalized_normals(tmp_path):
    path = tmp_path / "points.xyz"
    path.write_text("# exported by hand\n\nX;Y;Z;NX;NY;NZ\n0 0 0  0 0 2   # first\n\n1 2 3 3 0 4\n")
    points, normals = read_points(path)
    np.testing.assert_array_equal(points, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_allclose(normals, [[0, 0, 1], [0.6, 0, 0.8]])


@pytest.mark.parametrize("text, line, words", [
    ("0 0 0\n1 1 1\n2 2\n", 3, "2 columns"),
    ("x,y,z\n0,0,0\n1,1,1,1\n", 3, "4 columns"),
    ("0 0 0\n1 one 1\n", 2, "'one'"),
    ("0 0 0 0 0\n", 1, "5 columns"),
])
def test_text_points_bad_row_names_file_and_line(tmp_path, text, line, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InvalidInputError) as caught:
        read_points(path)
    message = str(caught.value)
    assert str(path) in message and f"line {line}" in message and words in message


def test_text_points_with_text_columns_only_says_which_line(tmp_path):
    path = tmp_path / "labelled.txt"
    path.write_text("x\ty\tz\tlabel\n1\t2\t3\tLV\n")
    with pytest.raises(InvalidInputError, match=r"it has a label column: these are labelled contours"):
        read_points(path)


def test_text_points_need_neither_vtk_nor_meshio(tmp_path):
    """bitemesh.io imports VTK and meshio lazily: text points read where neither is importable."""
    path = tmp_path / "points.csv"
    path.write_text("x,y,z\n0,0,0\n1,2,3\n")
    code = ("import sys; sys.modules['vtkmodules'] = None; sys.modules['meshio'] = None\n"
            "from bitemesh.io import read_points\n"
            f"points, normals = read_points({str(path)!r})\n"
            "assert points.tolist() == [[0, 0, 0], [1, 2, 3]] and normals is None\n")
    filters = Path(bitemesh.__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(filters), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


# ------------------------------------------------------------------------------------------- VTK points


def write_vtk(surface, path: Path):
    suffix = path.suffix
    if suffix == ".vtp":
        from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter as Writer
    elif suffix == ".vtk":
        from vtkmodules.vtkIOLegacy import vtkPolyDataWriter as Writer
    elif suffix == ".ply":
        from vtkmodules.vtkIOPLY import vtkPLYWriter as Writer
    elif suffix == ".obj":
        from vtkmodules.vtkIOGeometry import vtkOBJWriter as Writer
    else:
        from vtkmodules.vtkIOGeometry import vtkSTLWriter as Writer
    writer = Writer()
    writer.SetInputData(surface)
    writer.SetFileName(str(path))
    assert writer.Write() == 1
    return path


def outward_fraction(points, normals):
    return np.mean(np.einsum("ij,ij->i", points - points.mean(axis=0), normals) > 0)


@pytest.mark.parametrize("extension", [".vtp", ".vtk", ".ply", ".obj", ".stl"])
@pytest.mark.parametrize("with_normals", [True, False])
def test_vtk_surface_points_and_outward_unit_normals(tmp_path, vtk_silent, extension, with_normals):
    path = write_vtk(sphere(normals=with_normals), tmp_path / f"sphere{extension}")

    points, normals = read_points(path)

    assert points.shape == (SPHERE_POINTS, 3) and points.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 2.0, rtol=1e-5)  # float32, ASCII legacy
    assert normals is not None and normals.shape == points.shape
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=1e-6)
    assert outward_fraction(points, normals) > 0.95
    vtk_silent()


@pytest.mark.parametrize("extension", [".vtp", ".ply", ".stl"])
def test_inward_wound_closed_surface_gets_outward_normals(tmp_path, extension):
    """Polygons wound inward and no normals in the file: a closed surface is auto-oriented outward."""
    path = write_vtk(sphere(normals=False, reverse=True), tmp_path / f"inward{extension}")
    points, normals = read_points(path)
    assert outward_fraction(points, normals) > 0.95


@pytest.mark.parametrize("reverse", [False, True])
def test_open_surface_normals_follow_polygon_order(tmp_path, reverse):
    """An open surface is not auto-oriented: the normals are consistent and follow the winding of the file."""
    path = write_vtk(sphere(normals=False, reverse=reverse, hemisphere=True), tmp_path / "cap.vtp")
    points, normals = read_points(path)
    outward = np.einsum("ij,ij->i", points, normals) > 0  # the cap's centre of curvature is the origin
    assert np.mean(outward != reverse) > 0.95


def test_file_normals_are_used_as_given(tmp_path):
    """Normals stored in the file win over the polygons (here deliberately inward on an outward-wound sphere)."""
    from vtkmodules.util.numpy_support import numpy_to_vtk

    surface = sphere(normals=False)
    from vtkmodules.util.numpy_support import vtk_to_numpy

    inward = -vtk_to_numpy(surface.GetPoints().GetData()) / 2.0
    array = numpy_to_vtk(np.ascontiguousarray(inward), deep=True)
    array.SetName("Normals")
    surface.GetPointData().SetNormals(array)
    points, normals = read_points(write_vtk(surface, tmp_path / "inward_normals.vtp"))
    np.testing.assert_allclose(normals, -points / 2.0, atol=1e-6)


def test_point_cloud_without_polygons_has_no_normals(tmp_path):
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    points = vtkPoints()
    vertices = vtkCellArray()
    for i, xyz in enumerate([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]):
        points.InsertNextPoint(xyz)
        vertices.InsertNextCell(1)
        vertices.InsertCellPoint(i)
    cloud = vtkPolyData()
    cloud.SetPoints(points)
    cloud.SetVerts(vertices)
    read, normals = read_points(write_vtk(cloud, tmp_path / "cloud.vtp"))
    np.testing.assert_array_equal(read, [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)])
    assert normals is None


def test_unstructured_grids_give_points_and_surface_normals(tmp_path):
    """A .vtu/.vtk of tetrahedra gives its boundary surface's points with outward normals; one of triangles gives
    computed normals."""
    path = tmp_path / "cube.vtu"
    write_mesh(cube_mesh(), path)
    points, normals = read_points(path)
    np.testing.assert_array_equal(np.unique(points, axis=0), np.unique(cube_mesh().points, axis=0))
    assert outward_fraction(points, normals) == 1.0

    from vtkmodules.util.numpy_support import vtk_to_numpy

    surface = sphere(normals=False)
    triangles = vtk_to_numpy(surface.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    coordinates = vtk_to_numpy(surface.GetPoints().GetData()).astype(float)
    meshio.write(tmp_path / "sphere.vtk", meshio.Mesh(coordinates, [("triangle", triangles)]), file_format="vtk42")
    points, normals = read_points(tmp_path / "sphere.vtk")
    assert points.shape == (SPHERE_POINTS, 3)
    assert outward_fraction(points, normals) > 0.95


def test_bivme_legacy_5_1_file(vtk_silent, shared_data):
    """A VTK 5.1 legacy file (OFFSETS/CONNECTIVITY), open surface, no normals (``shared_data``: tests/conftest.py)."""
    path = shared_data / "bivme_patient1" / "patient1_LV_ENDOCARDIAL_000.vtk"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    points, normals = read_points(path)
    assert points.shape == (1572, 3)
    assert normals.shape == (1572, 3)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=1e-9)
    assert -75 < points[:, 0].min() and points[:, 0].max() < 57  # the GP-file bounding box, mm
    vtk_silent()

# ------------------------------------------------------------------------------------------- errors


GARBAGE = {
    ".ply": b"garbage\nnot a ply file\n",
    ".vtp": b"<not xml",
    ".vtu": b"\x00\x01\x02 binary junk",
    ".vtk": b"hello world\n1 2 3\n",
    ".obj": b"this is not an obj\n",
    ".stl": b"solid nothing\nendsolid nothing\n",
    ".xyz": b"# only a comment\n",
}


@pytest.mark.parametrize("extension", sorted(GARBAGE))
def test_garbage_point_files_raise_and_vtk_prints_nothing(tmp_path, vtk_silent, extension):
    from vtkmodules.vtkCommonCore import vtkObject

    path = tmp_path / f"garbage{extension}"
    path.write_bytes(GARBAGE[extension])
    with pytest.raises(InvalidInputError) as caught:
        read_points(path)
    assert str(path) in str(caught.value)
    vtk_silent()
    assert vtkObject.GetGlobalWarningDisplay() == 1  # restored


@pytest.mark.parametrize("extension", [".vtp", ".ply", ".stl"])
def test_truncated_point_files_raise(tmp_path, vtk_silent, extension):
    """Cut in the middle (vtkPLYReader would crash the interpreter on the truncated PLY)."""
    whole = write_vtk(sphere(), tmp_path / f"whole{extension}").read_bytes()
    path = tmp_path / f"truncated{extension}"
    path.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(InvalidInputError) as caught:
        read_points(path)
    assert str(path) in str(caught.value)
    vtk_silent()


@pytest.mark.parametrize("extension", sorted(POINT_EXTENSIONS))
def test_missing_and_empty_point_files(tmp_path, vtk_silent, extension):
    missing = tmp_path / f"missing{extension}"
    with pytest.raises(InvalidInputError, match="does not exist") as caught:
        read_points(missing)
    assert str(missing) in str(caught.value)
    empty = tmp_path / f"empty{extension}"
    empty.write_bytes(b"")
    with pytest.raises(InvalidInputError, match="is empty") as caught:
        read_points(empty)
    assert str(empty) in str(caught.value)
    vtk_silent()


def test_surface_points_that_no_polygon_uses_are_left_out(tmp_path):
    """Like the Stanford bunny's OBJ (1,113 unused duplicate vertices): they have no normal, so they go."""
    path = tmp_path / "stray.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    points, normals = read_points(path)
    assert len(points) == 4 and not np.any(np.all(points == 5, axis=1))
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert outward_fraction(points - points.mean(axis=0), normals) == 1.0


def test_the_stanford_bunny_reads_with_a_normal_for_every_point(shared_data):
    points, normals = read_points(shared_data / "stanford_bunny" / "stanford-bunny.obj")
    assert len(points) == 34834 and np.allclose(np.linalg.norm(normals, axis=1), 1.0)
