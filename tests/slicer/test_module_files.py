"""The module's files and parameters: the parameter specs follow the core dataclasses, the requirements install
only scipy, the .ui file binds every parameter, BiteMesh.py has the Slicer classes and builds its parameter node
class, the self-test cases pass headless, and the extension and checkout layouts find bitemesh.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from dataclasses import fields
from pathlib import Path
from xml.etree import ElementTree

import bitemesh
import numpy as np
import pytest
from bitemesh import InvalidInputError
from bitemesh.core.parameters import (BitingParameters, ImplicitParameters, LabelledParameters, QualityParameters,
                                      SpuriousParameters)

from tests.slicer.scenes import MODULE, BiteMeshLogic
from BiteMeshLib import logic as bitemesh_logic  # on sys.path from tests.slicer.scenes
from BiteMeshLib import parameters as lib_parameters
from BiteMeshLib import requirements as lib_requirements
from BiteMeshLib import selftest


# --- parameters, requirements, the module's files -------------------------------------------------------------------

def test_parameter_specs_follow_the_core_dataclasses():
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs()}
    assert list(specs) == list(lib_parameters.PARAMETERS)
    from bitemesh.core.parameters import FidelityParameters, OptimizeSwitch
    classes = {cls.__name__: cls for cls in (ImplicitParameters, BitingParameters, SpuriousParameters,
                                             QualityParameters, OptimizeSwitch, LabelledParameters,
                                             FidelityParameters)}
    for name, (dataclass_name, field_name) in lib_parameters.PARAMETERS.items():
        item = {f.name: f for f in fields(classes[dataclass_name])}[field_name]
        spec = specs[name]
        assert spec.core == field_name and spec.help == item.metadata["help"]
        if "choices" in item.metadata:
            assert spec.choices == item.metadata["choices"] and spec.default == item.default
        elif item.metadata.get("text"):
            assert spec.kind is str and spec.choices is None and spec.default == item.default
        else:
            low, high, low_open, _ = item.metadata["range"]
            assert spec.low == low and spec.lowOpen == low_open
            assert spec.high == (None if high is None or high == float("inf") else high)
            assert (spec.automatic is not None) == (item.default is None)
    assert specs["radius"].automatic == 0.0 and specs["radius"].kind is float
    assert specs["cells"].kind is int and specs["cells"].default == 10000
    assert (specs["threshold"].low, specs["threshold"].high) == (0.0, 1.0)
    assert specs["method"].choices == ("mpu", "rbf")
    assert (specs["domain"].kind, specs["domain"].default, specs["domain"].choices) == (str, "", None)
    assert specs["basePlane"].choices == ("auto", "valves", "none") and specs["basePlane"].default == "auto"
    # "automatic" is never a valid value of the core, so it cannot be confused with one
    for spec in specs.values():
        if spec.automatic is not None:
            with pytest.raises(InvalidInputError):
                classes[lib_parameters.PARAMETERS[spec.name][0]](**{spec.core: spec.automatic})
    assert lib_parameters.coreParameters({"radius": 0.0, "gridSpacing": 0.5, "method": "rbf", "cells": 500}) == \
        {"radius": None, "grid_spacing": 0.5, "method": "rbf", "cells": 500}
    assert lib_parameters.coreParameters({"domain": "EPI - LV_ENDO", "basePlane": "none"}) == \
        {"domain": "EPI - LV_ENDO", "base_plane": "none"}


def test_requirements_install_only_scipy(monkeypatch):
    import importlib.util
    calls = []
    assert lib_requirements.missingRequirements() == []
    assert lib_requirements.installRequirements(pipInstall=calls.append) == [] and calls == []

    real_find_spec = importlib.util.find_spec
    state = {"installed": False}

    def find_spec(name, *arguments):
        if name == "scipy" and not state["installed"]:
            return None
        return real_find_spec(name, *arguments)

    def pip(requirements):
        calls.append(list(requirements))
        state["installed"] = True

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    assert lib_requirements.missingRequirements() == ["scipy>=1.9"]
    with pytest.raises(lib_requirements.MissingRequirementError, match="not installed"):
        lib_requirements.installRequirements(pipInstall=pip, confirm=lambda missing: False)
    assert calls == []
    assert lib_requirements.installRequirements(pipInstall=pip) == ["scipy>=1.9"]
    assert calls == [["scipy>=1.9", f"numpy=={np.__version__}"]]   # numpy pinned as bundled, never upgraded
    assert not any(name in " ".join(calls[0]).lower() for name in ("vtk", "simpleitk", "itk"))


def test_ui_file_binds_every_parameter():
    tree = ElementTree.parse(MODULE / "Resources" / "UI" / "BiteMesh.ui")
    bound = {}
    for widget in tree.iter("widget"):
        for prop in widget.findall("property"):
            if prop.get("name") == "SlicerParameterName":
                bound[prop.find("string").text] = widget.get("class")
    assert set(lib_parameters.PARAMETERS) <= set(bound)
    assert set(bound) - set(lib_parameters.PARAMETERS) == {"inputNode", "outputModel"}
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs()}
    for name, widget_class in bound.items():
        spec = specs.get(name)
        expected = ("qMRMLNodeComboBox" if spec is None else "QComboBox" if spec.choices else
                    "QLineEdit" if spec.kind is str else "QSpinBox" if spec.kind is int else "QDoubleSpinBox")
        assert widget_class == expected, name   # the widget types parameterNodeWrapper connects
    names = {widget.get("name") for widget in tree.iter("widget")}
    assert {"applyButton", "cancelButton", "progressBar", "segmentComboBox", "contoursSelector",
            "loadLabelledPointsButton"} <= names


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


LOAD_MODULE_FILE = """
import sys, types, typing
# Stand-ins for what only the Slicer application has (Qt, ScriptedLoadableModule, parameterNodeWrapper).
sys.modules["qt"] = types.ModuleType("qt")
scripted = types.ModuleType("slicer.ScriptedLoadableModule")
for name in ("ScriptedLoadableModule", "ScriptedLoadableModuleWidget", "ScriptedLoadableModuleTest",
             "ScriptedLoadableModuleLogic"):
    setattr(scripted, name, type(name, (), {"__init__": lambda self, parent=None: setattr(self, "parent", parent)}))
sys.modules["slicer.ScriptedLoadableModule"] = scripted
wrapper = types.ModuleType("slicer.parameterNodeWrapper")
class Validator:
    def __init__(self, *arguments):
        self.arguments = arguments
class Choice(Validator):
    def validate(self, value):
        assert value in self.arguments[0], value
class Minimum(Validator):
    def validate(self, value):
        assert value >= self.arguments[0], value
class WithinRange(Validator):
    def validate(self, value):
        assert self.arguments[0] <= value <= self.arguments[1], value
wrapper.Choice, wrapper.Minimum, wrapper.WithinRange = Choice, Minimum, WithinRange
wrapper.parameterNodeWrapper = lambda cls: cls
sys.modules["slicer.parameterNodeWrapper"] = wrapper
import slicer
slicer.parameterNodeWrapper = wrapper
sys.path.insert(0, sys.argv[1])
import BiteMesh

module = BiteMesh.BiteMesh(types.SimpleNamespace())
assert module.parent.title == "BiteMesh" and module.parent.categories
cls = BiteMesh.parameterNodeClass()
hints = typing.get_type_hints(cls, include_extras=True)
assert type(None) in typing.get_args(hints["inputNode"]), "inputNode must allow None"
assert typing.get_args(hints["contours"])[0] is slicer.vtkMRMLMarkupsClosedCurveNode
for spec in BiteMesh.BiteMeshLogic.parameterSpecs():
    kind, *validators = typing.get_args(hints[spec.name]) or (hints[spec.name],)   # free text: plain str
    assert kind is spec.kind, spec.name
    for validator in validators:
        validator.validate(getattr(cls, spec.name))   # every default passes its own range
    if kind is int:
        assert all(max(validator.arguments) <= 2**31 - 1 for validator in validators), spec.name
print(sorted(hints))
"""


def test_module_file_builds_its_parameter_node_class():
    """BiteMesh.py loads (with stand-ins for Qt and the wrapper) and its parameter node follows the specs."""
    completed = subprocess.run([sys.executable, "-c", LOAD_MODULE_FILE, str(MODULE)], capture_output=True,
                               text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr
    names = ast.literal_eval(completed.stdout.strip().splitlines()[-1])
    assert set(names) == set(lib_parameters.PARAMETERS) | {"inputNode", "contours", "segmentId", "outputModel"}
