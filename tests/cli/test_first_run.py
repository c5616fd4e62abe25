"""The first run after ``pip install .`` (issue 35): the wheel's build compiles the numba kernels into it
(setup.py), so that the first ``bitemesh demo`` loads them (a run with numba's cache empty compiles about 170)."""
import importlib.metadata
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bitemesh.io import read_mesh

ROOT = Path(__file__).resolve().parents[2]


def pip(*args) -> None:
    subprocess.run([sys.executable, "-m", "pip", "-q", *map(str, args)], check=True, capture_output=True)


def installed_package(folder: Path) -> bool:
    """Copy into ``folder`` the bitemesh package as pip installed it from its wheel (the files its RECORD lists, no
    cache entry written since), when the tests run beside that install (the README's test command, CI); False when
    no installed bitemesh carries numba's caches (an editable install).  Found by its RECORD, not by the package
    imported: a source tree on sys.path (the Slicer tests put filters/ there) holds bitemesh.egg-info too."""
    for distribution in importlib.metadata.distributions(name="bitemesh"):
        files = [file for file in distribution.files or () if file.parts[0] == "bitemesh"]
        if any(file.suffix == ".nbi" for file in files):
            for file in files:
                (folder / file).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(distribution.locate_file(file), folder / file)
            return True
    return False


@pytest.mark.slow
def test_the_first_demo_after_pip_install_compiles_no_kernel(tmp_path):
    """The package pip installed for these tests (a wheel it built), or in an editable checkout a wheel built from
    a clean copy of the source (about 70 s); its first demo compiles nothing."""
    installed = tmp_path / "installed"
    if not installed_package(installed):
        source = tmp_path / "source"   # the checkout as a new user clones it: no earlier build, no cache
        shutil.copytree(ROOT / "filters", source / "filters", ignore=shutil.ignore_patterns("__pycache__"))
        for name in ("pyproject.toml", "setup.py", "README.md"):
            shutil.copy(ROOT / name, source)
        pip("wheel", "--no-deps", source, "-w", tmp_path)
        wheel = next(tmp_path.glob("bitemesh-*.whl"))
        pip("install", "--no-deps", "--target", installed, wheel)
    cached = [str(path) for path in installed.rglob("*.nbi")]
    assert any("kernels.newton_to_surface" in name for name in cached), cached
    caches = {path: path.stat().st_mtime_ns for path in installed.rglob("*.nb[ic]")}
    environment = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}
    run = subprocess.run([sys.executable, "-m", "bitemesh.cli", "demo", "-o", tmp_path / "die.vtu"], text=True,
                         capture_output=True, env={**environment, "PYTHONPATH": str(installed)}, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    # numba writes every kernel it compiles into its cache (a new entry in the index, a new data file): none
    assert {path: path.stat().st_mtime_ns for path in installed.rglob("*.nb[ic]")} == caches
    mesh = read_mesh(tmp_path / "die.vtu")
    assert len(mesh.cells) > 5000 and (mesh.cell_data["Volume"] > 0).all()
