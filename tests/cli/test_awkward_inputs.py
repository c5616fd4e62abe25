"""Input as users bring it: every awkward input ends in a mesh that follows the data, or in exit 1 with a message
that names the cause.  Never a silently wrong mesh, never a traceback, never a lost file.

Each case builds its own variant of a small sphere (1,500 points, radius 1): the classes of the trust issue
(column layouts, decimal marks, outliers, far coordinates, thin shapes, volume meshes as input, parameters out
of range, defective meshes for ``quality``) and more of each.  A mesh counts as following the data when it is a
valid domain, its volume is that of the shape within the chord error of ~3,000 cells (3 %), and the fidelity
check passed (its line is printed).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli
from bitemesh.core import shapes
from bitemesh.core.mesh import Mesh
from bitemesh.io import read_mesh, write_mesh

from tests.meshcheck import assert_valid_domain

SPHERE = 4 / 3 * np.pi
CELLS = ["--cells", "3000"]


@pytest.fixture(scope="module")
def sphere_samples():
    """(points, unit outward normals) on the unit sphere, about 0.1 apart."""
    return shapes.sample_surface(shapes.sphere(), spacing=0.1, seed=0)


def mesh_cli(capsys, tmp_path, source, *options):
    """Run ``bitemesh mesh source -o out.vtu options``: (exit code, stdout, stderr, output path)."""
    output = tmp_path / "out.vtu"
    code = cli.main(["mesh", str(source), "-o", str(output), *CELLS, *map(str, options)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err, output


def assert_follows(code, out, err, output, volume=SPHERE, tolerance=0.03):
    """The run wrote a valid mesh of the expected volume, and printed the fidelity it measured."""
    assert code == 0, err
    assert "fidelity: samples to boundary" in out
    assert_valid_domain(read_mesh(output), measure=volume, measure_tolerance=tolerance)


def assert_refused(code, err, *words):
    """Exit 1 with one error line that holds every one of ``words``."""
    assert code == 1, err
    errors = [line for line in err.splitlines() if line.startswith("bitemesh: error:")]
    assert len(errors) == 1, err
    for word in words:
        assert word in errors[0], errors[0]


def write_table(path, rows, header=None, separator=" ", decimal="."):
    lines = [separator.join(header)] if header else []
    for row in rows:
        lines.append(separator.join(f"{value:.6f}".replace(".", decimal) for value in row))
    path.write_text("\n".join(lines) + "\n")
    return path


# --- columns -------------------------------------------------------------------------------------------------

def test_colour_columns_without_header_are_refused_with_the_columns_hint(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_table(tmp_path / "cloud.xyz", np.hstack([points, colours]))
    code, _, err, output = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "not unit vectors", "--columns x,y,z,skip,skip,skip")
    assert not output.exists()


def test_colour_columns_read_past_with_columns(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_table(tmp_path / "cloud.xyz", np.hstack([points, colours]))
    assert_follows(*mesh_cli(capsys, tmp_path, path, "--columns", "x,y,z,skip,skip,skip"))


def test_colour_columns_named_by_a_header_are_read_past_with_a_note(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_table(tmp_path / "cloud.csv", np.hstack([points, colours]), header=["x", "y", "z", "r", "g", "b"],
                       separator=",")
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "columns r, g, b not used" in err


def test_unit_normals_without_header_are_used_and_said(capsys, tmp_path, sphere_samples):
    path = write_table(tmp_path / "cloud.xyz", np.hstack(sphere_samples))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "read as normals" in err


def test_a_header_with_units_and_other_names(capsys, tmp_path, sphere_samples):
    points, normals = sphere_samples
    path = write_table(tmp_path / "cloud.csv", np.hstack([normals, points]),
                       header=["Normal_X", "Normal_Y", "Normal_Z", "X [mm]", "Y [mm]", "Z [mm]"], separator=",")
    assert_follows(*mesh_cli(capsys, tmp_path, path))


def test_a_byte_order_mark_and_windows_line_ends(capsys, tmp_path, sphere_samples):
    path = tmp_path / "cloud.csv"
    text = "x,y,z\r\n" + "".join(f"{x:.6f},{y:.6f},{z:.6f}\r\n" for x, y, z in sphere_samples[0])
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert_follows(*mesh_cli(capsys, tmp_path, path))


@pytest.mark.parametrize("width", [5, 7])
def test_an_unknown_column_count_without_header_is_refused(capsys, tmp_path, sphere_samples, width):
    points, _ = sphere_samples
    extra = np.ones((len(points), width - 3))
    path = write_table(tmp_path / "cloud.txt", np.hstack([points, extra]))
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, f"{width} columns", "--columns")


def test_a_header_that_names_no_coordinates_is_refused(capsys, tmp_path, sphere_samples):
    path = write_table(tmp_path / "cloud.csv", sphere_samples[0], header=["a", "b", "c"], separator=",")
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "names no x and y columns", "--columns")


@pytest.mark.parametrize("columns, words", [
    ("x,y", ["names 2 columns", "has 3"]),
    ("x,y,colour", ["unknown role 'colour'"]),
    ("x,x,z", ["gives x twice"]),
])
def test_bad_columns_are_named(capsys, tmp_path, sphere_samples, columns, words):
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--columns", columns)
    assert_refused(code, err, *words)


def test_a_gpfile_without_its_label_column_is_refused(capsys, tmp_path, shared_data):
    lines = (shared_data / "bivme_patient1" / "GPFile_000.txt").read_text().splitlines()
    rows = [line.split("\t") for line in lines]
    path = tmp_path / "GPFile_nolabel.txt"
    path.write_text("\n".join("\t".join(row[:3] + row[4:]) for row in rows) + "\n")
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "no label column", "contour type")


def test_labelled_flags_on_plain_points_are_named(capsys, tmp_path, sphere_samples):
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--domain", "EPI - LV_ENDO")
    assert_refused(code, err, "--domain applies to labelled contours")


# --- decimal marks -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("separator", [";", "\t", " "])
def test_decimal_commas_are_read_as_decimals(capsys, tmp_path, sphere_samples, separator):
    path = write_table(tmp_path / "cloud.csv", sphere_samples[0], separator=separator, decimal=",")
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "decimal comma" in err
    reference = write_table(tmp_path / "dots.csv", sphere_samples[0])
    cli.main(["mesh", str(reference), "-o", str(tmp_path / "dots.vtu"), *CELLS])
    capsys.readouterr()
    np.testing.assert_array_equal(read_mesh(output).points, read_mesh(tmp_path / "dots.vtu").points)


def test_thousands_separators_are_refused(capsys, tmp_path):
    path = tmp_path / "cloud.csv"
    path.write_text("1.000,5;2,5;3,5\n" * 20)
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "both a decimal point and a comma")


# --- outliers ------------------------------------------------------------------------------------------------

def test_far_outliers_are_dropped_and_reported(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    far = np.random.default_rng(2).uniform(-30, 30, (len(points) // 100, 3))
    path = write_table(tmp_path / "cloud.xyz", np.vstack([points, far]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert f"dropped {len(far)} outliers" in err


def test_far_outliers_kept_on_request_are_refused_by_the_fidelity_check(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    far = np.random.default_rng(2).uniform(-30, 30, (len(points) // 100, 3))
    path = write_table(tmp_path / "cloud.xyz", np.vstack([points, far]))
    code, _, err, output = mesh_cli(capsys, tmp_path, path, "--outliers", "keep")
    assert_refused(code, err, "does not follow the data", "outliers")
    assert not output.exists()


def test_near_outliers_end_in_a_faithful_mesh_or_a_refusal(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    rng = np.random.default_rng(3)
    direction = rng.normal(size=(200, 3))
    near = direction / np.linalg.norm(direction, axis=1, keepdims=True) * rng.uniform(1.1, 1.6, (200, 1))
    path = write_table(tmp_path / "cloud.xyz", np.vstack([points, near]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    if code == 0:
        assert_follows(code, out, err, output)
    else:
        assert_refused(code, err, "does not follow the data")


def test_allow_unfaithful_keeps_the_mesh_with_a_loud_warning(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    far = np.random.default_rng(2).uniform(-30, 30, (len(points) // 100, 3))
    path = write_table(tmp_path / "cloud.xyz", np.vstack([points, far]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path, "--outliers", "keep", "--allow-unfaithful")
    assert code == 0 and output.exists()
    assert "bitemesh: warning: the mesh does not follow the data" in err


# --- coordinates far from the origin, rotated, scaled ---------------------------------------------------------

def rotation(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = np.radians(degrees)
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


@pytest.mark.parametrize("offset, turn, scale", [
    (1e7, 0.0, 1.0), (5e5, 37.0, 1.0), (0.0, 0.0, 1e-6), (0.0, 0.0, 1e6), (-3e6, 120.0, 1e-3)])
def test_scanner_coordinates_give_the_same_mesh_moved(tmp_path, sphere_samples, offset, turn, scale):
    points, normals = sphere_samples
    turned = rotation([1, 2, 3], turn)
    moved = points @ turned.T * scale + offset
    from bitemesh.core.pipeline import run
    result = run(moved, normals @ turned.T, biting=_cells(3000))
    mesh = result.mesh
    assert_valid_domain(mesh, measure=SPHERE * scale**3, measure_tolerance=0.03)
    from bitemesh.core.topology import boundary_facets
    back = (mesh.points[np.unique(boundary_facets(mesh.cells))] - offset) / scale @ turned
    assert np.abs(np.linalg.norm(back, axis=1) - 1).max() < 0.1 * result.radius / scale
    assert result.fidelity.far_samples == 0


def _cells(count):
    from bitemesh.core.parameters import BitingParameters
    return BitingParameters(cells=count)


# --- shapes that are hard for the method ----------------------------------------------------------------------

def test_a_plate_thinner_than_its_sampling_is_refused_with_a_cause(capsys, tmp_path):
    grid = np.linspace(-1, 1, 41)
    x, y = (axis.ravel() for axis in np.meshgrid(grid, grid))
    plate = np.vstack([np.c_[x, y, np.full_like(x, 0.02)], np.c_[x, y, np.full_like(x, -0.02)]])
    path = write_table(tmp_path / "plate.xyz", plate)
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    if code == 0:
        assert_follows(code, out, err, output, volume=4 * 0.04, tolerance=0.1)
    else:
        assert code == 1 and "bitemesh: error:" in err and not output.exists()


def test_a_thin_cylinder_gets_about_the_cells_asked_for(capsys, tmp_path):
    rng = np.random.default_rng(4)
    height, angle, radius = rng.uniform(-1, 1, 4000), rng.uniform(0, 2 * np.pi, 4000), 0.05
    wall = np.c_[radius * np.cos(angle), radius * np.sin(angle), height]
    disc = np.sqrt(rng.uniform(0, 1, 400)) * radius
    turn = rng.uniform(0, 2 * np.pi, 400)
    caps = np.c_[disc * np.cos(turn), disc * np.sin(turn), np.where(np.arange(400) % 2, 1.0, -1.0)]
    path = write_table(tmp_path / "rod.xyz", np.vstack([wall, caps]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    # R comes out about 0.3 rod diameters: ~11 edges around the rod, whose polygon has 5 % less area, and the
    # boundary nodes on the cylinder's curved wall lose about as much again
    assert_follows(code, out, err, output, volume=np.pi * radius**2 * 2, tolerance=0.15)
    assert 1500 <= len(read_mesh(output).cells) <= 6000   # 3000 asked


def test_touching_spheres_end_in_a_faithful_mesh_or_a_refusal(capsys, tmp_path, sphere_samples):
    points, _ = sphere_samples
    path = write_table(tmp_path / "pair.xyz", np.vstack([points - [1, 0, 0], points + [1, 0, 0]]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    if code == 0:
        assert_follows(code, out, err, output, volume=2 * SPHERE, tolerance=0.05)
    else:
        assert_refused(code, err, "does not follow the data")


def test_a_volume_mesh_as_input_is_meshed_from_its_boundary(capsys, tmp_path, sphere_samples):
    from bitemesh.core.pipeline import run
    volume = run(*sphere_samples, biting=_cells(8000)).mesh
    path = tmp_path / "volume.vtu"
    write_mesh(volume, path)
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output, volume=float(volume.cell_data["Volume"].sum()), tolerance=0.02)
    assert "is a volume mesh" in err


def test_zero_margin_does_not_clip_the_mesh(capsys, tmp_path, sphere_samples):
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0] + [0.31, 0.72, 0.23])
    assert_follows(*mesh_cli(capsys, tmp_path, path, "--margin", "0"), tolerance=0.03)


def test_every_point_twice_and_inward_normals(capsys, tmp_path, sphere_samples):
    points, normals = sphere_samples
    path = write_table(tmp_path / "cloud.xyz", np.vstack([np.hstack([points, -normals])] * 2))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "flipped" in err


def test_inconsistent_normals_are_refused(capsys, tmp_path, sphere_samples):
    points, normals = sphere_samples
    signs = np.where(np.random.default_rng(5).uniform(size=len(points)) < 0.5, -1.0, 1.0)
    path = write_table(tmp_path / "cloud.xyz", np.hstack([points, normals * signs[:, None]]))
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "normals")


# --- parameters out of range ----------------------------------------------------------------------------------

@pytest.mark.parametrize("options, words", [
    (["--grid-spacing", "5"], ["grid_spacing 5", "quarter of the data's longest side", "grid_spacing <="]),
    (["--radius", "1e-5"], ["radius >= ", "max_memory_mb"]),
    (["--radius", "inf"], ["radius must be a finite number"]),
    (["--radius", "50"], ["radius must be in", "cannot exceed"]),
    (["--cells", "10"], ["cells must be in [100"]),
    (["--threshold", "2"], ["threshold must be in [0, 1], got 2"]),
    (["--far-samples", "-1"], ["far_samples must be in [0, 100]"]),
    (["--outliers", "maybe"], []),
])
def test_parameters_out_of_range_are_named_at_once(capsys, tmp_path, sphere_samples, options, words):
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    output = tmp_path / "out.vtu"
    try:
        code = cli.main(["mesh", str(path), "-o", str(output), *options])
    except SystemExit as usage:   # argparse refuses a choice that is not one
        code = usage.code
    _, err = capsys.readouterr()
    assert code in (1, 2) and "Traceback" not in err
    for word in words:
        assert word in err, err


def test_the_memory_hint_fits(capsys, tmp_path, sphere_samples):
    """The radius the memory refusal suggests is accepted at the same memory bound."""
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--radius", "0.001", "--max-memory-mb", "64")
    assert code == 1
    suggested = float(err.split("radius >= ")[1].split()[0])
    from bitemesh.core.pipeline import run
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters
    result = run(sphere_samples[0], None, ImplicitParameters(max_memory_mb=64), BitingParameters(radius=suggested))
    assert result.mesh.cells.size


def test_a_grid_over_the_free_memory_is_refused_in_a_moment(monkeypatch, capsys, tmp_path, sphere_samples):
    """--max-memory-mb above what the machine has: the machine's free memory bounds the grid, before the fit."""
    import time

    import bitemesh.core.grid as grid
    import bitemesh.core.spine as spine
    for module in (grid, spine):
        monkeypatch.setattr(module, "available_memory_mb", lambda: 500.0)
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    clock = time.perf_counter()
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--grid-spacing", "0.004", "--max-memory-mb", "1000000")
    assert time.perf_counter() - clock < 5
    assert_refused(code, err, "the 500 MiB of memory this machine has free", "grid_spacing >= ")


def test_a_missing_output_folder_is_refused_before_any_work(capsys, tmp_path, sphere_samples):
    path = write_table(tmp_path / "cloud.xyz", sphere_samples[0])
    code = cli.main(["mesh", str(path), "-o", str(tmp_path / "absent" / "out.vtu")])
    _, err = capsys.readouterr()
    assert_refused(code, err, "does not exist")


def test_nan_rows_are_named_by_their_line(capsys, tmp_path, sphere_samples):
    points = sphere_samples[0].copy()
    points[4, 2] = np.nan
    path = write_table(tmp_path / "cloud.xyz", points, header=["x", "y", "z"])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "NaN", "line 6")


# --- the API names its arguments ------------------------------------------------------------------------------

@pytest.mark.parametrize("points, normals, words", [
    (np.array([["a", "b", "c"]] * 20), None, ["points must be"]),
    (np.zeros((20, 4)), None, ["points must be an (n, k) array"]),
    ("sphere", "wrong shape", ["normals must have the shape of points"]),
    ("sphere", "zeros", ["normals", "zero-length"]),
])
def test_the_api_names_the_bad_argument(sphere_samples, points, normals, words):
    import bitemesh
    if isinstance(points, str):
        points = sphere_samples[0]
    normals = {"wrong shape": np.ones((5, 3)), "zeros": np.zeros_like(points), None: None}[normals]
    with pytest.raises(bitemesh.InvalidInputError) as caught:
        bitemesh.mesh_from_points(points, normals, cells=1000)
    for word in words:
        assert word in str(caught.value)


# --- bitemesh quality reports defects ------------------------------------------------------------------------

def small_mesh(sphere_samples):
    from bitemesh.core.pipeline import run
    return run(*sphere_samples, biting=_cells(1500)).mesh


@pytest.mark.parametrize("defect, words", [
    ("inverted", ["inverted cells"]),
    ("duplicated", ["cells with the same vertices as another cell"]),
    ("flat", ["flat cells"]),
    ("unused", ["points used by no cell"]),
])
def test_quality_reports_defects_instead_of_repairing_them(capsys, tmp_path, sphere_samples, defect, words):
    mesh = small_mesh(sphere_samples)
    points, cells = mesh.points, mesh.cells.copy()
    if defect == "inverted":
        cells[:100, :2] = cells[:100, 1::-1]
    elif defect == "duplicated":
        cells = np.vstack([cells, cells])
    elif defect == "flat":
        points = np.vstack([points, points[cells[0, :3]].mean(axis=0)])
        cells = np.vstack([cells, [[cells[0, 0], cells[0, 1], cells[0, 2], len(points) - 1]]])
    else:
        points = np.vstack([points, [[9.0, 9.0, 9.0]]])
    path = tmp_path / "defective.vtu"
    write_mesh(Mesh(points, cells), path)
    code = cli.main(["quality", str(path)])
    out, err = capsys.readouterr()
    assert code == 1 and "defects:" in out and "Traceback" not in err
    for word in words:
        assert word in out


def test_quality_of_a_truncated_file_says_why(capsys, tmp_path, sphere_samples):
    path = tmp_path / "mesh.vtu"
    write_mesh(small_mesh(sphere_samples), path)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    code = cli.main(["quality", str(path)])
    _, err = capsys.readouterr()
    assert_refused(code, err, "mesh.vtu", "truncated")
