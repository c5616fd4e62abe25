"""``python -m bitemesh.cli`` as a separate program: its version, its exit codes, a closed output pipe."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import bitemesh

from tests.cli.commands import assert_no_traceback

FILTERS = Path(bitemesh.__file__).resolve().parents[1]

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
