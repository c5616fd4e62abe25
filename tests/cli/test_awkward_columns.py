"""Awkward columns and decimal marks: colour columns, normals without a header, headers with units, a byte
order mark, unknown column counts, --columns, a GPFile without its labels, decimal commas, thousands separators.

Input as users bring it: every awkward input ends in a mesh that follows the data, or in exit 1 with a message
that names the cause.  Never a silently wrong mesh, never a traceback, never a lost file.  Each case builds its own
variant of a small sphere (``unit_sphere_samples``: 1,500 points, radius 1, tests/conftest.py); a mesh counts as
following the data when it is a valid domain, its volume is that of the shape within the chord error of ~3,000 cells
(3 %), and the fidelity check passed (its line is printed).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli
from bitemesh.io import read_mesh

from tests.cli.commands import CELLS, assert_follows, assert_refused, mesh_cli, write_rows

# --- columns -------------------------------------------------------------------------------------------------

def test_colour_columns_without_header_are_refused_with_the_columns_hint(capsys, tmp_path, unit_sphere_samples):
    points, _ = unit_sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_rows(tmp_path / "cloud.xyz", np.hstack([points, colours]))
    code, _, err, output = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "not unit vectors", "--columns x,y,z,skip,skip,skip")
    assert not output.exists()


def test_x_y_z_and_an_intensity_without_header_are_read_as_3d_points(capsys, tmp_path, unit_sphere_samples):
    """Four columns whose last two are no unit vectors: x y z and a value (a scanner's intensity), said in a note;
    not 2-D points with normals, which --columns x,y,nx,ny still reads."""
    points, _ = unit_sphere_samples
    intensity = np.random.default_rng(2).uniform(0, 255, (len(points), 1))
    path = write_rows(tmp_path / "scan.txt", np.hstack([points, intensity]))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "read as x y z and a value (column 4 not used)" in err


def test_a_nan_normal_is_named_by_its_line(capsys, tmp_path, unit_sphere_samples):
    points, normals = unit_sphere_samples
    rows = np.hstack([points, normals])
    rows[37, 4] = np.nan
    code, _, err, output = mesh_cli(capsys, tmp_path, write_rows(tmp_path / "cloud.xyz", rows))
    assert_refused(code, err, "line 38 has NaN or infinite normals")
    assert "length" not in err and not output.exists()


def gpfile_rows(shared_data) -> list:
    """The shipped biv-me GPFile's rows (its header first), each a list of its tab-separated fields."""
    return [line.split("\t") for line in (shared_data / "bivme_patient1" / "GPFile_000.txt").read_text().splitlines()]


def gpfile_without_column(shared_data, path, column: int):
    """The shipped GPFile written to ``path`` without its ``column`` (0: x, 2: z, 3: the label)."""
    path.write_text("\n".join("\t".join(row[:column] + row[column + 1:]) for row in gpfile_rows(shared_data)) + "\n")
    return path


def test_binary_data_is_no_table(capsys, tmp_path):
    path = tmp_path / "scan.xyz"
    path.write_bytes(np.random.default_rng(3).bytes(4000))
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "not a text table", ".ply")
    assert "thousands separator" not in err


def test_labelled_contours_without_z_and_in_metres_are_refused_with_their_cause(capsys, tmp_path, shared_data):
    code, _, err, _ = mesh_cli(capsys, tmp_path, gpfile_without_column(shared_data, tmp_path / "noz.txt", 2))
    assert_refused(code, err, "names no z column", "restore the z column")
    headless = tmp_path / "noz_noheader.txt"   # and without its header: the label is in column 3, not a colour
    headless.write_text("".join((tmp_path / "noz.txt").read_text().splitlines(keepends=True)[1:]))
    code, _, err, _ = mesh_cli(capsys, tmp_path, headless)
    assert_refused(code, err, "column 3 of line 1 holds text", "a coordinate column is missing before it")
    rows = gpfile_rows(shared_data)
    metres = tmp_path / "metres.txt"
    metres.write_text("\n".join(["\t".join(rows[0])] + ["\t".join([f"{float(value) / 1000:.8f}" for value in row[:3]]
                                                                   + row[3:]) for row in rows[1:]]) + "\n")
    code, _, err, _ = mesh_cli(capsys, tmp_path, metres)
    assert_refused(code, err, "in metres?", "multiply them by 1000")
    assert "NaN" not in err


def test_label_zero_is_out_of_the_range_help_gives(capsys, tmp_path):
    import SimpleITK as sitk
    with pytest.raises(SystemExit):
        cli.main(["mesh", "--help"])
    assert "range [1, inf]" in " ".join(capsys.readouterr().out.split())
    ball = (np.linalg.norm(np.indices((20, 20, 20)) - 9.5, axis=0) < 7).astype(np.uint8)
    sitk.WriteImage(sitk.GetImageFromArray(ball), str(tmp_path / "ball.nrrd"))
    code, _, err, _ = mesh_cli(capsys, tmp_path, tmp_path / "ball.nrrd", "--label", "0")
    assert_refused(code, err, "label must be in [1, inf], got 0")


def test_colour_columns_read_past_with_columns(capsys, tmp_path, unit_sphere_samples):
    points, _ = unit_sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_rows(tmp_path / "cloud.xyz", np.hstack([points, colours]))
    assert_follows(*mesh_cli(capsys, tmp_path, path, "--columns", "x,y,z,skip,skip,skip"))


def test_colour_columns_named_by_a_header_are_read_past_with_a_note(capsys, tmp_path, unit_sphere_samples):
    points, _ = unit_sphere_samples
    colours = np.random.default_rng(1).integers(0, 256, (len(points), 3))
    path = write_rows(tmp_path / "cloud.csv", np.hstack([points, colours]), header=["x", "y", "z", "r", "g", "b"],
                       separator=",")
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "columns r, g, b not used" in err


def test_unit_normals_without_header_are_used_and_said(capsys, tmp_path, unit_sphere_samples):
    path = write_rows(tmp_path / "cloud.xyz", np.hstack(unit_sphere_samples))
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "read as normals" in err


def test_a_header_with_units_and_other_names(capsys, tmp_path, unit_sphere_samples):
    points, normals = unit_sphere_samples
    path = write_rows(tmp_path / "cloud.csv", np.hstack([normals, points]),
                       header=["Normal_X", "Normal_Y", "Normal_Z", "X [mm]", "Y [mm]", "Z [mm]"], separator=",")
    assert_follows(*mesh_cli(capsys, tmp_path, path))


def test_a_byte_order_mark_and_windows_line_ends(capsys, tmp_path, unit_sphere_samples):
    path = tmp_path / "cloud.csv"
    text = "x,y,z\r\n" + "".join(f"{x:.6f},{y:.6f},{z:.6f}\r\n" for x, y, z in unit_sphere_samples[0])
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert_follows(*mesh_cli(capsys, tmp_path, path))


@pytest.mark.parametrize("width", [5, 7])
def test_an_unknown_column_count_without_header_is_refused(capsys, tmp_path, unit_sphere_samples, width):
    points, _ = unit_sphere_samples
    extra = np.ones((len(points), width - 3))
    path = write_rows(tmp_path / "cloud.txt", np.hstack([points, extra]))
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, f"{width} columns", "--columns")


def test_a_header_that_names_no_coordinates_is_refused(capsys, tmp_path, unit_sphere_samples):
    path = write_rows(tmp_path / "cloud.csv", unit_sphere_samples[0], header=["a", "b", "c"], separator=",")
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "names no x and y columns", "--columns")


@pytest.mark.parametrize("columns, words", [
    ("x,y", ["names 2 columns", "has 3"]),
    ("x,y,colour", ["unknown role 'colour'"]),
    ("x,x,z", ["gives x twice"]),
])
def test_bad_columns_are_named(capsys, tmp_path, unit_sphere_samples, columns, words):
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--columns", columns)
    assert_refused(code, err, *words)


def test_a_gpfile_without_its_label_column_is_refused(capsys, tmp_path, shared_data):
    code, _, err, _ = mesh_cli(capsys, tmp_path, gpfile_without_column(shared_data, tmp_path / "nolabel.txt", 3))
    assert_refused(code, err, "no label column", "contour type")


def test_labelled_flags_on_plain_points_are_named(capsys, tmp_path, unit_sphere_samples):
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--domain", "EPI - LV_ENDO")
    assert_refused(code, err, "--domain applies to labelled contours")


def test_label_map_flags_on_points_are_named(capsys, tmp_path, unit_sphere_samples):
    """--ras (a label map's RAS output) on points was ignored in silence (the same mesh, exit 0), as --label is
    not."""
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--ras")
    assert_refused(code, err, "--ras applies to label maps", "leave it out")


# --- decimal marks -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("separator", [";", "\t", " "])
def test_decimal_commas_are_read_as_decimals(capsys, tmp_path, unit_sphere_samples, separator):
    path = write_rows(tmp_path / "cloud.csv", unit_sphere_samples[0], separator=separator, decimal=",")
    code, out, err, output = mesh_cli(capsys, tmp_path, path)
    assert_follows(code, out, err, output)
    assert "decimal comma" in err
    reference = write_rows(tmp_path / "dots.csv", unit_sphere_samples[0])
    cli.main(["mesh", str(reference), "-o", str(tmp_path / "dots.vtu"), *CELLS])
    capsys.readouterr()
    np.testing.assert_array_equal(read_mesh(output).points, read_mesh(tmp_path / "dots.vtu").points)


def test_thousands_separators_are_refused(capsys, tmp_path):
    path = tmp_path / "cloud.csv"
    path.write_text("1.000,5;2,5;3,5\n" * 20)
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "both a decimal point and a comma")


def test_labelled_contours_in_micrometres_or_with_another_unit_are_refused_naming_it(capsys, tmp_path, shared_data):
    """A GPFile in micrometres is named as such before the grid is sized (it asked for 664 TB, then for a radius
    that gave 1.2 million cells and a refusal); --unit m on a GPFile in metres is answered, not ignored; following
    either hint (the file in mm, no --unit) meshes."""
    rows = gpfile_rows(shared_data)

    def scaled(factor, name):
        path = tmp_path / name
        path.write_text("\n".join(["\t".join(rows[0])] + ["\t".join([f"{float(value) * factor:.8f}" for value in
                                                                     row[:3]] + row[3:]) for row in rows[1:]]) + "\n")
        return path

    code, _, err, _ = mesh_cli(capsys, tmp_path, scaled(1000.0, "microns.txt"))
    assert_refused(code, err, "in micrometres?", "divide them by 1000")
    code, _, err, _ = mesh_cli(capsys, tmp_path, scaled(0.001, "metres.txt"), "--unit", "m")
    assert_refused(code, err, "--unit m", "multiply them by 1000", "leave --unit out")
    code, _, err, output = mesh_cli(capsys, tmp_path, scaled(1.0, "mm.txt"), "--cells", "8000")
    assert code == 0 and output.exists(), err
