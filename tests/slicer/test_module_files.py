"""The module's files: the requirements install only scipy, BiteMesh.py has the Slicer classes, the self-test cases
pass headless, and the extension and checkout layouts find bitemesh (the panel and its parameters: test_panel.py).

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import bitemesh
import numpy as np
import pytest

from tests.slicer.scenes import MODULE, BiteMeshLogic
from BiteMeshLib import logic as bitemesh_logic  # on sys.path from tests.slicer.scenes
from BiteMeshLib import requirements as lib_requirements
from BiteMeshLib import selftest


# --- requirements, the module's files -------------------------------------------------------------------------------

def test_requirements_install_only_what_is_missing_then_compile_the_kernels(monkeypatch):
    import importlib.util
    calls = []
    assert lib_requirements.missingRequirements() == []
    assert lib_requirements.installRequirements(pipInstall=calls.append) == [] and calls == []

    real_find_spec = importlib.util.find_spec
    state = {"installed": False}

    def find_spec(name, *arguments):
        if name in ("scipy", "numba") and not state["installed"]:
            return None
        return real_find_spec(name, *arguments)

    def pip(requirements):
        calls.append(list(requirements))
        state["installed"] = True

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    assert lib_requirements.missingRequirements() == ["scipy>=1.9", "numba>=0.56"]
    with pytest.raises(lib_requirements.MissingRequirementError, match="not installed"):
        lib_requirements.installRequirements(pipInstall=pip, confirm=lambda missing: False)
    assert calls == []
    # then bitemesh's kernels compiled into numba's cache (bitemesh.meshing.compile_kernels, as pip install . does)
    monkeypatch.setattr("bitemesh.meshing.compile_kernels", lambda: calls.append("kernels compiled"))
    assert lib_requirements.installRequirements(pipInstall=pip) == ["scipy>=1.9", "numba>=0.56"]
    # numpy pinned as bundled, never upgraded
    assert calls == [["scipy>=1.9", "numba>=0.56", f"numpy=={np.__version__}"], "kernels compiled"]
    assert not any(name in " ".join(calls[0]).lower() for name in ("vtk", "simpleitk", "itk"))


def test_module_file_has_the_slicer_classes():
    source = (MODULE / "BiteMesh.py").read_text()
    module = ast.parse(source)
    classes = {node.name: [ast.unparse(base) for base in node.bases] for node in module.body
               if isinstance(node, ast.ClassDef)}
    assert classes["BiteMesh"] == ["ScriptedLoadableModule"]
    assert "ScriptedLoadableModuleWidget" in classes["BiteMeshWidget"]
    assert classes["BiteMeshTest"] == ["ScriptedLoadableModuleTest"]
    assert "from BiteMeshLib.logic import" in source and "BiteMeshLogic" in source
    assert "tryWithErrorDisplay" in source and "print(" not in source
    assert issubclass(BiteMeshLogic, bitemesh_logic.ScriptedLoadableModuleLogic)


def test_self_test_cases_pass_headless(scene, logic):
    """The cases BiteMeshTest runs in Slicer, on a slicer-core scene."""
    for case in selftest.CASES:
        case(scene, logic)


RUN_FROM_LAYOUT = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np, slicer
from BiteMeshLib.logic import BiteMeshLogic
import bitemesh
scene = slicer.vtkMRMLScene()
points = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode")
directions = np.random.default_rng(0).normal(size=(400, 3))
for point in 10 * directions / np.linalg.norm(directions, axis=1, keepdims=True):
    points.AddControlPoint(*map(float, point))
model = scene.AddNewNodeByClass("vtkMRMLModelNode")
result = BiteMeshLogic().process(points, model, radius=3.0)
print(bitemesh.__file__)
print(model.GetMesh().GetNumberOfCells())
"""


def run_module(module_dir, cwd):
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    completed = subprocess.run([sys.executable, "-c", RUN_FROM_LAYOUT, str(module_dir)], cwd=cwd, env=environment,
                               capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stderr
    where, cells = completed.stdout.split()[-2:]
    assert int(cells) > 100
    return Path(where)


def test_extension_layout_ships_bitemesh(tmp_path):
    """As installed by the extension: BiteMesh.py, BiteMeshLib/ and bitemesh/ side by side (no PYTHONPATH)."""
    lib = tmp_path / "lib" / "Slicer-5.8" / "qt-scripted-modules"
    shutil.copytree(MODULE / "BiteMeshLib", lib / "BiteMeshLib", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(MODULE / "BiteMesh.py", lib)
    package = Path(bitemesh.__file__).parent
    shutil.copytree(package, lib / "bitemesh", ignore=shutil.ignore_patterns("__pycache__", "cli"))
    assert run_module(lib, tmp_path) == lib / "bitemesh" / "__init__.py"


def test_checkout_layout_finds_filters(tmp_path):
    """As added to Slicer's module paths from a checkout: bitemesh found in filters/ beside slicer_module/."""
    where = run_module(MODULE, tmp_path)
    assert where == MODULE.parents[1] / "filters" / "bitemesh" / "__init__.py"

