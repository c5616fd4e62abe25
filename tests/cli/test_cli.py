"""The ``bitemesh`` command line: mesh, quality, demo; exit codes, one-line errors, cancellation, progress bar.

Small meshes (about 2000 cells of the unit sphere sampled every 0.08) keep the whole file well under a minute.
"""
import contextlib
import io
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import bitemesh
import numpy as np
import pytest
from bitemesh import cli
from bitemesh.cli import options as cli_options
from bitemesh.cli.options import ProgressBar
from bitemesh.core import pipeline
from bitemesh.core.errors import Cancelled
from bitemesh.core.parameters import BitingParameters, ImplicitParameters
from bitemesh.core.quality import quality_summary, radius_ratio
from bitemesh.core.shapes import annulus, die, sample_surface, sphere
from bitemesh.io import MESH_EXTENSIONS, read_mesh

from tests.meshcheck import assert_valid_domain

FILTERS = Path(bitemesh.__file__).resolve().parents[1]
SPHERE_VOLUME = 4 / 3 * np.pi
# A mesh of about 2000 cells has R = 0.22: its boundary is a polyhedron inscribed in the sphere (the mesh volume
# equals the convex hull of its boundary nodes), 3.1 % smaller than the ball. Finer meshes come closer.
SPHERE_TOLERANCE = 0.04
STEPS = ("implicit fit", "implicit sampling", "biting", "delaunay", "spurious cells", "quality", "total")


# --------------------------------------------------------------------------------------------- helpers


def write_table(path: Path, points, normals=None, delimiter=" ", header=None) -> Path:
    table = points if normals is None else np.hstack([points, normals])
    np.savetxt(path, table, delimiter=delimiter, header=header or "", comments="")
    return path


def run_quietly(argv) -> int:
    """``main(argv)`` with its output thrown away (for fixtures, which cannot use capsys)."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return cli.main(argv)


def assert_no_traceback(text: str) -> None:
    assert "Traceback" not in text and 'File "' not in text, text


def assert_one_line_error(capsys, code: int, *names: str) -> str:
    """Exit code 1 and exactly one stderr line "bitemesh: error: ..." that matches every regex in ``names``."""
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 1, (out, err)
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("bitemesh: error: "), err
    for name in names:
        assert re.search(name, lines[0]), f"{name!r} not in {lines[0]!r}"
    return lines[0]


def terminal_view(text: str) -> list:
    """What a terminal shows for ``text``: each carriage return goes back to column 0 and overwrites."""
    rows = []
    for line in text.split("\n"):
        row = ""
        for part in line.split("\r"):
            row = part + row[len(part):]
        rows.append(row)
    return rows


def mean_q_printed(stdout: str) -> float:
    match = re.search(r"^radius ratio Q\s+mean (\d\.\d{4})\s", stdout, re.MULTILINE)
    assert match, stdout
    return float(match.group(1))


# --------------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Scattered points of the unit sphere in several files, and of an annulus (2D, with normals)."""
    folder = tmp_path_factory.mktemp("inputs")
    points, normals = sample_surface(sphere(), 0.08, seed=1)
    files = {
        "xyz+normals": write_table(folder / "sphere_n.xyz", points, normals),
        "xyz": write_table(folder / "sphere.xyz", points),
        "csv+header": write_table(folder / "sphere.csv", points, normals, delimiter=",", header="x,y,z,nx,ny,nz"),
        "txt": write_table(folder / "sphere.txt", points),
    }
    ring, ring_normals = sample_surface(annulus(), 0.05, seed=1)
    files["annulus"] = write_table(folder / "annulus.xyz", ring, ring_normals)
    return files


@pytest.fixture(scope="module")
def reference(inputs, tmp_path_factory):
    """The sphere meshed once by ``bitemesh mesh --cells 2000`` (seed 0), as a .vtu."""
    path = tmp_path_factory.mktemp("reference") / "sphere.vtu"
    assert run_quietly(["mesh", str(inputs["xyz+normals"]), "-o", str(path), "--cells", "2000"]) == 0
    return path


@pytest.fixture
def pipeline_spy(monkeypatch):
    """Records whether ``bitemesh mesh`` reached the pipeline."""
    calls = []

    def spy(*args, **kwargs):
        calls.append(args)
        return pipeline.run(*args, **kwargs)
    monkeypatch.setattr(cli.mesh, "run_pipeline", spy)
    return calls


# --------------------------------------------------------------------------------------------- mesh


@pytest.mark.parametrize("kind", ["xyz+normals", "xyz", "csv+header", "stl"])
def test_mesh_writes_a_valid_sphere_and_reports(kind, inputs, tmp_path, capsys):
    if kind == "stl":
        from vtkmodules.vtkFiltersSources import vtkSphereSource
        from vtkmodules.vtkIOGeometry import vtkSTLWriter
        source = vtkSphereSource()
        source.SetRadius(1.0)
        source.SetThetaResolution(40)
        source.SetPhiResolution(40)
        writer = vtkSTLWriter()
        writer.SetInputConnection(source.GetOutputPort())
        source_file = tmp_path / "sphere.stl"
        writer.SetFileName(str(source_file))
        writer.Write()
    else:
        source_file = inputs[kind]
    output = tmp_path / "sphere.vtu"
    code = cli.main(["mesh", str(source_file), "-o", str(output), "--cells", "2000"])
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0, err
    mesh = read_mesh(output)
    assert mesh.cells.shape[1] == 4
    # The tessellated STL sphere is itself inscribed, so its volume is a little smaller still.
    assert_valid_domain(mesh, euler=2, components=1, measure=SPHERE_VOLUME,
                        measure_tolerance=SPHERE_TOLERANCE + (0.01 if kind == "stl" else 0))
    assert 1000 <= len(mesh.cells) <= 3000  # "about N cells"
    assert f"wrote {output} (radius R = " in out
    assert f"mesh            {len(mesh.cells)} tetrahedra, " in out
    assert mean_q_printed(out) == pytest.approx(radius_ratio(mesh.points, mesh.cells).mean(), abs=1e-4)
    assert "time per step:" in out
    for step in STEPS:
        assert re.search(rf"^  {step}\s+\d+\.\d\d s$", out, re.MULTILINE), (step, out)


def test_mesh_real_ply(shared_data, tmp_path, capsys):
    """The pyvista nut (shared_data: 523 sparse vertices of a closed genus-1 surface, volume about 32,171)."""
    output = tmp_path / "nut.vtu"
    code = cli.main(["mesh", str(shared_data / "pyvista_nut" / "nut.ply"), "-o", str(output), "--cells", "2000"])
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0, err
    mesh = read_mesh(output)
    assert_valid_domain(mesh, euler=0, components=1, measure=32171, measure_tolerance=0.1)
    assert 1000 <= len(mesh.cells) <= 3000


def test_default_cell_count_is_about_10000(inputs, tmp_path, capsys):
    output = tmp_path / "sphere.vtu"
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output)]) == 0
    assert 7000 <= len(read_mesh(output).cells) <= 13000


def test_radius_overrides_cells(inputs, reference, tmp_path, capsys):
    runs = {}
    for cells in ("2000", "50000"):
        output = tmp_path / f"r{cells}.vtu"
        code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--radius", "0.3", "--cells", cells])
        assert code == 0
        assert "radius R = 0.3)" in capsys.readouterr().out
        runs[cells] = read_mesh(output)
    # --cells is ignored once --radius is given ...
    assert np.array_equal(runs["2000"].cells, runs["50000"].cells)
    assert np.array_equal(runs["2000"].points, runs["50000"].points)
    # ... and the count follows R: about 5.4 V / R^3 = 840 cells, far fewer than the 2000 of the reference.
    count = len(runs["2000"].cells)
    assert count < 0.6 * len(read_mesh(reference).cells)
    assert 400 <= count <= 1300
    assert_valid_domain(runs["2000"], euler=2, components=1)


@pytest.mark.parametrize("extension", MESH_EXTENSIONS)
def test_every_output_format_reads_back(extension, inputs, reference, tmp_path, capsys):
    output = tmp_path / f"sphere{extension}"
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"]) == 0
    assert output.is_file()
    mesh, expected = read_mesh(output), read_mesh(reference)
    assert len(mesh.cells) == len(expected.cells)
    assert np.array_equal(mesh.cells, expected.cells)
    assert np.allclose(mesh.points, expected.points, atol=1e-6)
    assert_valid_domain(mesh, euler=2, components=1)


def test_2d_points_give_triangles(inputs, tmp_path, capsys):
    output = tmp_path / "annulus.vtu"
    code = cli.main(["mesh", str(inputs["annulus"]), "-o", str(output), "--cells", "2000", "--method", "rbf"])
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0, err
    mesh = read_mesh(output)
    assert mesh.points.shape[1] == 2 and mesh.cells.shape[1] == 3
    shape = annulus()
    assert_valid_domain(mesh, euler=shape.boundary_euler, components=1, measure=shape.measure,
                        measure_tolerance=0.03)
    assert 1000 <= len(mesh.cells) <= 3000
    assert f"{len(mesh.cells)} triangles" in out


def test_same_seed_same_mesh_other_seed_other_mesh(inputs, reference, tmp_path, capsys):
    again, other = tmp_path / "again.vtu", tmp_path / "other.vtu"
    arguments = ["mesh", str(inputs["xyz+normals"]), "--cells", "2000"]
    assert cli.main(arguments + ["-o", str(again), "--seed", "0"]) == 0
    assert cli.main(arguments + ["-o", str(other), "--seed", "1"]) == 0
    first, second, third = read_mesh(reference), read_mesh(again), read_mesh(other)
    assert np.array_equal(first.points, second.points) and np.array_equal(first.cells, second.cells)
    assert again.read_bytes() == reference.read_bytes()
    assert first.points.shape != third.points.shape or not np.array_equal(first.points, third.points)


# --------------------------------------------------------------------------------------------- quality


def test_quality_prints_the_summary(reference, capsys):
    assert cli.main(["quality", str(reference)]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    mesh = read_mesh(reference)
    assert out.startswith(f"{quality_summary(mesh)}\ndefects: none")
    assert out.startswith(f"mesh            {len(mesh.cells)} tetrahedra, {len(mesh.points)} points\n")
    assert mean_q_printed(out) == pytest.approx(radius_ratio(mesh.points, mesh.cells).mean(), abs=1e-4)


def test_quality_histogram_writes_a_png(reference, tmp_path, capsys):
    picture = tmp_path / "q.png"
    assert cli.main(["quality", str(reference), "--histogram", str(picture), "--bins", "10"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert f"wrote {picture}" in out
    data = picture.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 1000


@pytest.mark.parametrize("target, names", [("missing/q.png", [r"--histogram", "missing"]),
                                            ("q.xyz", [r"--histogram", "q.xyz"])])
def test_quality_histogram_bad_path_is_one_line(target, names, reference, tmp_path, capsys):
    code = cli.main(["quality", str(reference), "--histogram", str(tmp_path / target)])
    assert_one_line_error(capsys, code, *names)


def test_quality_of_a_bad_mesh_is_one_line(tmp_path, capsys):
    garbage = tmp_path / "garbage.vtu"
    garbage.write_text("not a mesh\n")
    assert_one_line_error(capsys, cli.main(["quality", str(garbage)]), "garbage.vtu")
    assert_one_line_error(capsys, cli.main(["quality", str(tmp_path / "none.vtu")]), "none.vtu", "does not exist")


def test_quality_bins_zero_is_one_line(reference, tmp_path, capsys):
    code = cli.main(["quality", str(reference), "--histogram", str(tmp_path / "q.png"), "--bins", "0"])
    _, err = capsys.readouterr()
    assert code == 1 and err.startswith("bitemesh: error: bins") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "q.png").exists()


# --------------------------------------------------------------------------------------------- demo


def test_demo_meshes_the_die(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.build_parser().parse_args(["demo"]).dataset == "die"   # written to die.vtu by default
    code = cli.main(["demo", "-o", "die.vtu"])
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0, err
    mesh = read_mesh(tmp_path / "die.vtu")
    assert 7000 <= len(mesh.cells) <= 13000
    assert_valid_domain(mesh, euler=2, components=1, mean_quality=0.78, measure=die().measure,
                        measure_tolerance=0.03)
    assert mean_q_printed(out) >= 0.78
    assert "wrote die.vtu" in out and "of the exact die" in out and "time per step:" in out


def test_demo_refuses_a_bad_output_before_work(tmp_path, monkeypatch, capsys):
    def forbidden(*args, **kwargs):
        raise AssertionError("the demo meshed before checking its output")
    monkeypatch.setattr(cli.demo, "run_pipeline", forbidden)
    assert_one_line_error(capsys, cli.main(["demo", "-o", str(tmp_path / "die.stl")]), r"\.stl")


# --------------------------------------------------------------------------------------------- exit codes


@pytest.mark.parametrize("argv", [
    [],
    ["--bogus"],
    ["frobnicate"],
    ["mesh", "{input}", "-o", "{output}", "--bogus"],
    ["mesh", "{input}", "-o", "{output}", "--method", "bogus"],
    ["mesh", "{input}", "-o", "{output}", "--order", "sideways"],
    ["mesh", "{input}", "-o", "{output}", "--cells", "many"],
    ["mesh", "{input}", "-o", "{output}", "--radius", "big"],
    ["mesh", "{input}"],
    ["mesh", "-o", "{output}"],
    ["quality"],
    ["demo", "--cells"],
], ids=lambda argv: " ".join(argv) or "(nothing)")
def test_usage_errors_exit_2(argv, inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / "out.vtu"
    argv = [word.format(input=inputs["xyz+normals"], output=output) for word in argv]
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    assert err.startswith("usage: bitemesh") and re.search(r"^bitemesh( \w+)?: error: ", err, re.MULTILINE), err
    assert pipeline_spy == [] and not output.exists()


def test_help_lists_commands_and_every_parameter(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["--help"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert all(command in out for command in ("mesh", "quality", "demo"))
    with pytest.raises(SystemExit) as stop:
        cli.main(["mesh", "--help"])
    assert stop.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    for flag in ("--radius", "--cells", "--grid-spacing", "--method {mpu,rbf}", "--error-bound", "--margin",
                 "--max-memory-mb", "--order", "--seed", "--threshold", "--min-component"):
        assert flag in out, flag
    assert "default 10000" in out and "default 4096.0" in out


def make_bad_input(kind: str, folder: Path, good: Path) -> Path:
    if kind == "good":
        return good
    points = np.loadtxt(good)[:, :3]
    path = folder / f"{kind}.xyz"
    if kind == "missing":
        return path
    if kind == "directory":
        path.mkdir()
    elif kind == "garbage":
        path.write_text("this is not\na table of numbers\n")
    elif kind == "garbage-vtp":
        path = folder / "garbage.vtp"
        path.write_bytes(bytes(range(256)) * 4)
    elif kind == "empty":
        path.write_text("")
    elif kind == "ragged":
        path.write_text("0 0 0\n1 0 0\n1 1\n")
    elif kind == "three":
        write_table(path, points[:3])
    elif kind == "nan":
        points[7, 1] = np.nan
        write_table(path, points)
    elif kind == "coplanar":
        points[:, 2] = 0.25
        write_table(path, points)
    else:
        raise ValueError(kind)
    return path


# (input kind, extra options, regexes the message must match, whether it fails before the pipeline is called)
BAD_INPUTS = {
    "missing file": ("missing", [], [r"missing\.xyz", "does not exist"], True),
    "directory": ("directory", [], [r"directory\.xyz", "not a regular file"], True),
    "garbage text": ("garbage", [], [r"garbage\.xyz", "no row holds numbers"], True),
    "garbage vtp": ("garbage-vtp", [], [r"garbage\.vtp"], True),
    "ragged rows": ("ragged", [], [r"ragged\.xyz", "line 3"], True),
    "empty file": ("empty", [], [r"empty\.xyz", "empty"], True),
    "3 points": ("three", [], ["points", r"\b3\b"], False),
    "NaN": ("nan", [], ["NaN", "line 8"], True),
    "coplanar": ("coplanar", [], ["points", "plane"], False),
    "radius -1": ("good", ["--radius", "-1"], [r"\bradius\b", "-1"], True),
    "radius 0": ("good", ["--radius", "0"], [r"\bradius\b"], True),
    "radius 50": ("good", ["--radius", "50"], [r"\bradius\b"], False),
    "radius 5": ("good", ["--radius", "5"], [r"\bradius\b"], False),
    "cells 5": ("good", ["--cells", "5"], [r"\bcells\b"], True),
    "grid spacing 0": ("good", ["--grid-spacing", "0"], [r"grid[_-]spacing"], True),
    "error bound 0": ("good", ["--error-bound", "0"], [r"error[_-]bound"], True),
    "margin -1": ("good", ["--margin", "-1"], [r"\bmargin\b"], True),
    "threshold 2": ("good", ["--threshold", "2"], [r"\bthreshold\b"], True),
    "min component 2": ("good", ["--min-component", "2"], [r"min[_-]component"], True),
    "memory": ("good", ["--max-memory-mb", "1", "--grid-spacing", "0.001"],
               [r"grid[_-]spacing", r"max[_-]memory[_-]mb"], False),
    "max memory 0": ("good", ["--max-memory-mb", "0"], [r"max[_-]memory[_-]mb"], True),
    "seed -1": ("good", ["--seed", "-1"], [r"\bseed\b"], True),
    "seed 2^32": ("good", ["--seed", str(2**32)], [r"\bseed\b"], True),
}


@pytest.mark.parametrize("kind, extra, names, early", list(BAD_INPUTS.values()), ids=list(BAD_INPUTS))
def test_bad_input_exits_1_with_one_line(kind, extra, names, early, inputs, tmp_path, capsys, pipeline_spy):
    source = make_bad_input(kind, tmp_path, inputs["xyz"])
    output = tmp_path / "out.vtu"
    code = cli.main(["mesh", str(source), "-o", str(output), "--cells", "2000"] + extra)
    message = assert_one_line_error(capsys, code, *names)
    assert not output.exists()
    if early:
        assert pipeline_spy == []
    for low, high in re.findall(r"must be in [\[(](\S+), (\S+?)[\])]", message):
        assert float(low) <= float(high), f"empty range in {message!r}"


def test_memory_cap_respects_the_given_grid_spacing(inputs, tmp_path, capsys):
    # A 0.1 grid of the unit sphere has about 30^3 nodes (0.2 MiB): it fits in 1 MiB.
    output = tmp_path / "out.vtu"
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000",
                     "--grid-spacing", "0.1", "--max-memory-mb", "1"])
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0 or "grid_spacing 0.1 " in err, err


@pytest.mark.parametrize("name", ["out.stl", "out", "out.vtu.txt"])
def test_unknown_output_extension_fails_before_meshing(name, inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / name
    clock = time.perf_counter()
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"])
    elapsed = time.perf_counter() - clock
    message = assert_one_line_error(capsys, code, re.escape(name), "extension")
    assert ".vtu" in message and ".msh" in message  # says what would work
    assert pipeline_spy == [] and elapsed < 2.0 and not output.exists()


def test_missing_output_directory_fails_before_meshing(inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / "no" / "such" / "out.vtu"
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"])
    assert_one_line_error(capsys, code, "does not exist", re.escape(str(output.parent)))
    assert pipeline_spy == []


def test_upper_case_output_extension_is_accepted(inputs, tmp_path, capsys):
    output = tmp_path / "SPHERE.VTU"
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--radius", "0.4"]) == 0
    assert len(read_mesh(output).cells) > 0


# --------------------------------------------------------------------------------------------- cancellation


@pytest.mark.parametrize("after", [0.0, 0.3, 0.5, 0.75])
def test_pipeline_cancels_with_cancelled(after, inputs):
    points = np.loadtxt(inputs["xyz+normals"])
    seen, calls_after = [], []

    def progress(fraction, message=""):
        if seen and seen[-1][0] > after:
            calls_after.append(fraction)  # called again after it raised: someone swallowed Cancelled
        seen.append((fraction, message))
        assert 0.0 <= fraction <= 1.0
        if fraction > after:
            raise Cancelled("stop")
    with pytest.raises(Cancelled) as raised:
        pipeline.run(points[:, :3], points[:, 3:], ImplicitParameters(), BitingParameters(cells=2000),
                     progress=progress)
    assert type(raised.value) is Cancelled
    assert calls_after == [] and seen[-1][0] > after


def test_progress_reaches_one_in_order(inputs):
    points = np.loadtxt(inputs["xyz+normals"])
    fractions = []
    pipeline.run(points[:, :3], points[:, 3:], ImplicitParameters(), BitingParameters(cells=2000),
                 progress=lambda fraction, message="": fractions.append(fraction))
    assert fractions[-1] == 1.0 and fractions == sorted(fractions) and len(fractions) >= 5


@pytest.mark.parametrize("command", ["mesh", "demo"])
@pytest.mark.parametrize("stop", [KeyboardInterrupt, Cancelled])
def test_interrupt_exits_130(command, stop, inputs, tmp_path, monkeypatch, capsys):
    def interrupted(*args, progress=None, **kwargs):
        progress(0.5, "biting")
        raise stop()
    monkeypatch.setattr(getattr(cli, command), "run_pipeline", interrupted)
    output = tmp_path / "out.vtu"
    argv = ["mesh", str(inputs["xyz+normals"])] if command == "mesh" else ["demo"]
    code = cli.main(argv + ["-o", str(output)])
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 130
    assert err.strip().splitlines()[-1] == "bitemesh: cancelled"
    assert not output.exists()


# --------------------------------------------------------------------------------------------- progress bar


def test_progress_bar_draws_percentages_and_ends_the_line():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0, width=20)
    for fraction, message in [(0.0, "fit"), (0.25, "sampling"), (0.25, "sampling"), (0.5, "biting"), (1.0, "done")]:
        bar(fraction, message)
    bar.close()
    text = stream.getvalue()
    assert text.startswith("\r[") and text.endswith("\n") and text.count("\n") == 1
    assert text.count("\r") == 4  # the repeated (0.25, "sampling") is not redrawn
    for percent in ("  0%", " 25%", " 50%", "100%"):
        assert percent in text
    assert "[#####               ]  25% sampling" in text
    assert terminal_view(text)[0].rstrip() == "[####################] 100% done"


def test_progress_bar_leaves_no_trace_of_a_longer_message():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0)
    bar(0.3, "sampling f on 157 x 157 x 157 nodes")
    bar(0.5, "biting")
    bar.close()
    assert terminal_view(stream.getvalue())[0].rstrip() == f"[{'#' * 15}{' ' * 15}]  50% biting"


def test_progress_bar_waits_for_the_delay(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(cli_options, "time", type("FakeTime", (), {"perf_counter": staticmethod(lambda: clock[0])}))
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=1.0)
    bar(0.2, "fit")
    clock[0] += 0.9
    bar(0.4, "sampling")
    assert stream.getvalue() == ""  # fast so far: nothing
    clock[0] += 0.2  # the step has now taken 1.1 s
    bar(0.6, "biting")
    assert " 60% biting" in stream.getvalue()
    clock[0] += 5
    bar(0.8, "repairing")
    bar.close()
    assert " 80% repairing" in stream.getvalue() and stream.getvalue().endswith("\n")


def test_progress_bar_prints_nothing_for_a_fast_run():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=1.0)
    for step in range(11):
        bar(step / 10, "step")
    bar.close()
    assert stream.getvalue() == ""


def test_mesh_shows_the_bar_on_stderr_when_slow(inputs, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cli.mesh, "ProgressBar", lambda: ProgressBar(delay=0))  # every step counts as slow
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(tmp_path / "s.vtu"), "--radius", "0.4"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert "\r[" in err and "100%" in err and err.endswith("\n")
    assert "\r" not in out and "[#" not in out  # the bar stays off stdout, which holds the report


# --------------------------------------------------------------------------------------------- as a program


def run_program(*arguments, **kwargs):
    environment = dict(os.environ, PYTHONPATH=str(FILTERS))
    return subprocess.run([sys.executable, "-m", "bitemesh.cli", *arguments], check=False, env=environment,
                          capture_output=True, text=True, timeout=120, **kwargs)


def test_version_as_a_program():
    finished = run_program("--version")
    assert finished.returncode == 0, finished.stderr
    assert finished.stdout.strip() == f"bitemesh {bitemesh.__version__}"


def test_program_exit_codes(tmp_path):
    assert run_program().returncode == 2
    finished = run_program("mesh", str(tmp_path / "missing.xyz"), "-o", str(tmp_path / "out.vtu"))
    assert finished.returncode == 1
    assert finished.stderr.strip().splitlines() == [
        f"bitemesh: error: cannot read points from '{tmp_path / 'missing.xyz'}': the file does not exist"]


def test_closed_output_pipe_is_quiet(reference):
    # bitemesh quality m.vtu | head -0: the reader is gone before bitemesh writes.
    environment = dict(os.environ, PYTHONPATH=str(FILTERS))
    process = subprocess.Popen([sys.executable, "-m", "bitemesh.cli", "quality", str(reference)], env=environment,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()
    err = process.stderr.read().decode()
    process.wait(timeout=120)
    assert_no_traceback(err)
    assert "Exception ignored" not in err and process.returncode in (0, 141)


def test_optimize_flag_gives_a_valid_mesh_without_slivers(inputs, tmp_path, capsys):
    from bitemesh.core.quality import quality_summary
    output = tmp_path / "optimized.vtu"
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "3000", "--optimize"]) == 0
    mesh = read_mesh(output)
    assert_valid_domain(mesh, euler=2, components=1)
    summary = quality_summary(mesh)
    assert summary.q_mean >= 0.88 and summary.angle_min >= 15 and summary.q_min >= 0.2
    assert "optimize" in capsys.readouterr().out


def test_a_label_map_file_is_meshed_in_its_physical_space(tmp_path, capsys):
    import SimpleITK as sitk
    grid = np.stack(np.meshgrid(*[np.arange(40)] * 3, indexing="ij"))
    ball = (np.linalg.norm(grid - 19.5, axis=0) <= 15).astype(np.uint8)
    image = sitk.GetImageFromArray(ball.T.copy())
    image.SetSpacing((0.5, 0.5, 0.5))
    image.SetOrigin((10.0, -5.0, 3.0))
    path = tmp_path / "ball.nrrd"
    sitk.WriteImage(image, str(path))
    output = tmp_path / "ball.vtu"
    assert cli.main(["mesh", str(path), "-o", str(output), "--cells", "3000"]) == 0
    mesh = read_mesh(output)
    assert_valid_domain(mesh, euler=2, components=1, measure=4 / 3 * np.pi * 7.5**3, measure_tolerance=0.03)
    np.testing.assert_allclose(mesh.points.mean(axis=0), [10 + 9.75, -5 + 9.75, 3 + 9.75], atol=0.3)
    assert cli.main(["mesh", str(path), "-o", str(output), "--label", "7"]) == 1
    assert "label" in capsys.readouterr().err


def test_a_gpfile_meshes_as_the_two_cavity_myocardium_without_flags(shared_data, tmp_path, capsys):
    gpfile = shared_data / "bivme_patient1" / "GPFile_000.txt"
    output = tmp_path / "heart.vtu"
    assert cli.main(["mesh", str(gpfile), "-o", str(output), "--cells", "20000"]) == 0
    mesh = read_mesh(output)
    assert_valid_domain(mesh, components=1)
    assert 120e3 < mesh.cell_data["Volume"].sum() < 220e3            # mm^3: a myocardium of about 170 ml
    assert cli.main(["mesh", str(gpfile), "-o", str(output), "--domain", "EPI - AORTA"]) == 1
    assert "AORTA" in capsys.readouterr().err


def test_demo_heart_meshes_the_shipped_guide_points(tmp_path, capsys):
    output = tmp_path / "heart.vtu"
    assert cli.main(["demo", "heart", "--cells", "20000", "-o", str(output)]) == 0
    assert_valid_domain(read_mesh(output), components=1)
    assert "biv-me" in capsys.readouterr().out


def test_labelled_flags_win_over_the_config_file(tmp_path, capsys):
    from tests.core.test_labelled import sample_shell
    from tests.vtk.test_labelled_filters import SHELL_VOLUME
    points, labels, slices = sample_shell(spacing=5.0, sax=tuple(range(-75, 80, 10)))
    contours = tmp_path / "shell.csv"
    contours.write_text("x,y,z,label,slice\n" + "".join(f"{x},{y},{z},{label},{number}\n" for (x, y, z), label,
                                                         number in zip(points, labels, slices)))
    config = tmp_path / "shell.json"
    config.write_text('{"domain": "EPI - LV_ENDO", "base_plane": "valves"}')
    output = tmp_path / "shell.vtu"
    assert cli.main(["mesh", str(contours), "-o", str(output), "--config", str(config)]) == 1
    assert "base_plane='valves' needs at least 3 points" in capsys.readouterr().err
    assert cli.main(["mesh", str(contours), "-o", str(output), "--config", str(config), "--cells", "6000",
                     "--domain", "EPI - LV_ENDO - RV_ENDO", "--base-plane", "none", "--min-wall", "3"]) == 0
    assert_valid_domain(read_mesh(output), euler=6, components=1, measure=SHELL_VOLUME, measure_tolerance=0.03)
