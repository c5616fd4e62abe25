"""The first run after ``pip install .`` (issue 35): the wheel's build compiles the numba kernels into it
(setup.py), so that the first ``bitemesh demo`` loads them (a run with numba's cache empty compiles about 170)."""
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from bitemesh.io import read_mesh

ROOT = Path(__file__).resolve().parents[2]


def pip(*args) -> None:
    subprocess.run([sys.executable, "-m", "pip", "-q", *map(str, args)], check=True, capture_output=True)


@pytest.mark.slow
def test_the_first_demo_after_pip_install_compiles_no_kernel(tmp_path):
    source = tmp_path / "source"   # the checkout as a new user clones it: no earlier build, no cache
    shutil.copytree(ROOT / "filters", source / "filters", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy(ROOT / name, source)
    pip("wheel", "--no-deps", source, "-w", tmp_path)
    wheel = next(tmp_path.glob("bitemesh-*.whl"))
    cached = [name for name in zipfile.ZipFile(wheel).namelist() if name.endswith(".nbi")]
    assert any("kernels.newton_to_surface" in name for name in cached), cached
    installed = tmp_path / "installed"
    pip("install", "--no-deps", "--target", installed, wheel)
    caches = {path: path.stat().st_mtime_ns for path in installed.rglob("*.nb[ic]")}
    environment = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}
    run = subprocess.run([sys.executable, "-m", "bitemesh.cli", "demo", "-o", tmp_path / "die.vtu"], text=True,
                         capture_output=True, env={**environment, "PYTHONPATH": str(installed)}, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    # numba writes every kernel it compiles into its cache (a new entry in the index, a new data file): none
    assert {path: path.stat().st_mtime_ns for path in installed.rglob("*.nb[ic]")} == caches
    mesh = read_mesh(tmp_path / "die.vtu")
    assert len(mesh.cells) > 5000 and (mesh.cell_data["Volume"] > 0).all()
