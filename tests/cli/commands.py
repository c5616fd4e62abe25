"""Running the ``bitemesh`` command in the tests, and what its output must look like: point files written for it,
one-line errors without a traceback, the quality report it prints, the checks of a mesh that follows its data."""
from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
from bitemesh import cli
from bitemesh.io import read_mesh

from tests.meshcheck import assert_valid_domain

SPHERE_VOLUME = 4 / 3 * np.pi
#: a small mesh of the awkward-input cases: the chord error of ~3,000 cells stays within 3 % of the volume
CELLS = ["--cells", "3000"]


def save_table(path: Path, points, normals=None, delimiter=" ", header=None) -> Path:
    """``points`` (and ``normals`` beside them) written by np.savetxt (full precision), with an optional header."""
    table = points if normals is None else np.hstack([points, normals])
    np.savetxt(path, table, delimiter=delimiter, header=header or "", comments="")
    return path


def write_rows(path, rows, header=None, separator=" ", decimal=".") -> Path:
    """``rows`` written with 6 decimals, ``separator`` between the values and ``decimal`` as the decimal mark."""
    lines = [separator.join(header)] if header else []
    for row in rows:
        lines.append(separator.join(f"{value:.6f}".replace(".", decimal) for value in row))
    path.write_text("\n".join(lines) + "\n")
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


def mean_q_printed(stdout: str) -> float:
    """The mean radius ratio the quality report printed."""
    match = re.search(r"^radius ratio Q\s+mean (\d\.\d{4})\s", stdout, re.MULTILINE)
    assert match, stdout
    return float(match.group(1))


def mesh_cli(capsys, tmp_path, source, *options):
    """Run ``bitemesh mesh source -o out.vtu --cells 3000 options`` (without ``--cells 3000`` when the options
    size the cells themselves): (exit code, stdout, stderr, output path)."""
    output = tmp_path / "out.vtu"
    options = [str(option) for option in options]
    sizing = [] if {"--radius", "--cells"} & set(options) else CELLS
    code = cli.main(["mesh", str(source), "-o", str(output), *sizing, *options])
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err, output


def assert_follows(code, out, err, output, volume=SPHERE_VOLUME, tolerance=0.03):
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
