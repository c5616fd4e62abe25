"""The ``bitemesh`` command's exit codes: 2 and argparse's usage for a bad command line, 1 and one line naming the
cause for bad input or parameters (before the pipeline runs where it can), and a bad output path refused before any
meshing."""
from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from bitemesh import cli
from bitemesh.io import read_mesh

from tests.cli.commands import assert_no_traceback, assert_one_line_error, save_table

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
    for flag in ("--radius", "--cells", "--grid-spacing", "--method {auto,mpu,rbf}", "--error-bound", "--margin",
                 "--max-memory-mb", "--order", "--seed", "--threshold", "--min-component"):
        assert flag in out, flag
    assert "else 10000" in out and "default 4096.0" in out


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
        save_table(path, points[:3])
    elif kind == "nan":
        points[7, 1] = np.nan
        save_table(path, points)
    elif kind == "coplanar":
        points[:, 2] = 0.25
        save_table(path, points)
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
    "radius -2": ("good", ["--radius", "-2"], [r"\bradius\b", "-2"], True),   # -1 is automatic
    "radius 0": ("good", ["--radius", "0"], [r"\bradius\b"], True),
    "radius 50": ("good", ["--radius", "50"], [r"\bradius\b"], False),
    "radius 5": ("good", ["--radius", "5"], [r"\bradius\b"], False),
    "cells 5": ("good", ["--cells", "5"], [r"\bcells\b"], True),
    "grid spacing 0": ("good", ["--grid-spacing", "0"], [r"grid[_-]spacing"], True),
    "error bound 0": ("good", ["--error-bound", "0"], [r"error[_-]bound"], True),
    "margin -2": ("good", ["--margin", "-2"], [r"\bmargin\b"], True),
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


@pytest.mark.parametrize("name", ["out.stl", "out.vtu.txt"])   # "out", no extension: a cardiac-geometries folder
def test_unknown_output_extension_fails_before_meshing(name, inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / name
    clock = time.perf_counter()
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"])
    elapsed = time.perf_counter() - clock
    message = assert_one_line_error(capsys, code, re.escape(name), "extension")
    assert ".vtu" in message and ".msh" in message  # says what would work
    assert pipeline_spy == [] and elapsed < 2.0 and not output.exists()


def test_an_output_without_extension_that_is_a_file_fails_before_meshing(inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / "heart"
    output.write_text("not a folder")
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"])
    assert_one_line_error(capsys, code, "heart", "is a file", "folder", ".vtu")
    assert pipeline_spy == [] and output.read_text() == "not a folder"


def test_missing_output_directory_fails_before_meshing(inputs, tmp_path, capsys, pipeline_spy):
    output = tmp_path / "no" / "such" / "out.vtu"
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000"])
    assert_one_line_error(capsys, code, "does not exist", re.escape(str(output.parent)))
    assert pipeline_spy == []


def test_upper_case_output_extension_is_accepted(inputs, tmp_path, capsys):
    output = tmp_path / "SPHERE.VTU"
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--radius", "0.4"]) == 0
    assert len(read_mesh(output).cells) > 0
