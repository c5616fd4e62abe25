"""The panel against the core dataclasses: every field of each dataclass the panel uses has a parameter, a widget
in the .ui (its section, type, label, unit suffix; no tooltip or range of its own) and a parameter-node field with
the dataclass's range and default; keywords split by dataclass, the optimizer's switch and bounds, unknown names
refused.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Everything but the parameter-node test runs in the main environment too (it needs no Slicer).
"""
from __future__ import annotations

import ast
import subprocess
import sys
from dataclasses import fields
from xml.etree import ElementTree

import pytest
from bitemesh import InvalidInputError
from bitemesh.core import parameters as core
from bitemesh.core.fem.fibres import FibreParameters

from tests.slicer.module import MODULE
from BiteMeshLib import parameters as lib_parameters  # on sys.path from tests.slicer.module

INT_MAX = 2**31 - 1   # QSpinBox's largest value (BiteMesh._INT_MAX)
#: the suffix a spin box shows for each unit of the dataclasses (Slicer's input units are mm).
UNIT_SUFFIX = {"": None, "input units": " mm", "mm": " mm", "MiB": " MiB", "degrees": "°", "%": " %"}
WIDGET_CLASSES = {"choices": "QComboBox", str: "QLineEdit", int: "QSpinBox", float: "QDoubleSpinBox",
                  bool: "QCheckBox"}


def core_field(name):
    """The dataclass field behind a panel parameter."""
    dataclass_name, field_name = {**lib_parameters.PARAMETERS, **lib_parameters.FIT_PARAMETERS}[name]
    return {item.name: item for item in fields(lib_parameters.coreDataclass(dataclass_name))}[field_name]


def ui_sections():
    """The .ui's collapsible sections, in order: object name -> (collapsed, [(label widget or None, widget)])."""
    root = ElementTree.parse(MODULE / "Resources" / "UI" / "BiteMesh.ui").getroot()
    sections = {}
    for button in root.iter("widget"):
        if button.get("class") != "ctkCollapsibleButton":
            continue
        collapsed = any(p.get("name") == "collapsed" and p.find("bool").text == "true"
                        for p in button.findall("property"))
        rows = {}
        for item in button.find("layout").findall("item"):
            widget = item.find("widget")
            if widget is not None:
                rows.setdefault(int(item.get("row")), {})[int(item.get("column"))] = widget
        sections[button.get("name")] = (collapsed, [(row.get(0), row[1]) for _, row in sorted(rows.items())
                                                    if 1 in row])
    return sections


def properties(widget) -> dict:
    """A widget's own properties: name -> text."""
    return {p.get("name"): (p[0].text if len(p) else None) for p in widget.findall("property")}


# --- the parameters and their specs ---------------------------------------------------------------------------------

def test_the_panel_has_every_field_of_its_dataclasses():
    """The labelled contours', the optimizer's and the fibres' parameters included: nothing left only to scripts."""
    used = set(lib_parameters.KEYWORDS.values())
    assert {"LabelledParameters", "OptimizeParameters", "ImplicitParameters", "FibreParameters"} <= used
    assert lib_parameters.coreDataclass("FibreParameters") is FibreParameters
    claimed = set(lib_parameters.PARAMETERS.values())
    for dataclass_name in used:
        for item in fields(lib_parameters.coreDataclass(dataclass_name)):
            assert (dataclass_name, item.name) in claimed, f"{dataclass_name}.{item.name} has no panel parameter"
    assert {lib_parameters.PARAMETERS[name] for name in ("iterations", "minDihedral", "minQuality")} == \
        {("OptimizeParameters", "iterations"), ("OptimizeParameters", "min_dihedral"),
         ("OptimizeParameters", "min_quality")}
    assert len(lib_parameters.KEYWORDS) == len(lib_parameters.PARAMETERS)   # one keyword per parameter
    assert list(lib_parameters.PARAMETERS) == [name for section in lib_parameters.SECTIONS.values()
                                               for name in section]


def test_parameter_specs_follow_the_core_dataclasses():
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs()}
    assert list(specs) == list(lib_parameters.PARAMETERS)
    for name, spec in specs.items():
        item = core_field(name)
        assert spec.core == item.name and spec.help == item.metadata["help"] and spec.unit == item.metadata["unit"]
        if "choices" in item.metadata:
            assert spec.choices == item.metadata["choices"] and spec.default == item.default
        elif item.metadata.get("text"):
            assert spec.kind is str and spec.choices is None and spec.default == item.default
        elif item.metadata["integer"] and item.metadata["range"][:2] == (0, 1):   # a switch: a check box
            assert spec.kind is bool and spec.default is bool(item.default) and spec.automatic is None
        else:
            low, high, low_open, _ = item.metadata["range"]
            assert spec.kind is (int if item.metadata["integer"] else float)
            assert spec.low == low and spec.lowOpen == low_open
            assert spec.high == (None if high is None or high == float("inf") else high)
            assert (spec.automatic is not None) == (item.default is None)
            assert spec.default == (core.AUTOMATIC if item.default is None else item.default)
    assert specs["radius"].automatic == -1.0 and specs["radius"].kind is float   # one number for "automatic"
    assert specs["minWall"].automatic == -1.0 and specs["margin"].automatic == -1.0   # 0 is a valid wall, margin
    assert (specs["iterations"].kind, specs["iterations"].default, specs["iterations"].high) == (int, 30, 1000)
    assert (specs["minDihedral"].default, specs["minDihedral"].high, specs["minDihedral"].unit) == \
        (20.0, 60.0, "degrees")
    assert (specs["rvWall"].default, specs["rvWall"].lowOpen) == (-1.0, True)   # automatic: 3 mm, or a small heart's
    assert specs["basePlane"].choices == ("auto", "valves", "none") and specs["basePlane"].default == "auto"
    # the fibres: a check box, off, and the four angles of Bayer et al. in [-90, 90] degrees
    assert (specs["fibres"].kind, specs["fibres"].default, specs["fibres"].core) == (bool, False, "fibres")
    assert {name: (specs[name].core, specs[name].kind, specs[name].default, specs[name].low, specs[name].high,
                   specs[name].unit) for name in ("alphaEndo", "alphaEpi", "betaEndo", "betaEpi")} == {
        "alphaEndo": ("alpha_endo", float, 40.0, -90.0, 90.0, "degrees"),
        "alphaEpi": ("alpha_epi", float, -50.0, -90.0, 90.0, "degrees"),
        "betaEndo": ("beta_endo", float, -65.0, -90.0, 90.0, "degrees"),
        "betaEpi": ("beta_epi", float, 25.0, -90.0, 90.0, "degrees")}
    # "automatic" is never a valid value of the core, so it cannot be confused with one
    for spec in specs.values():
        if spec.automatic is not None:
            with pytest.raises(InvalidInputError):
                lib_parameters.coreDataclass(lib_parameters.PARAMETERS[spec.name][0])(**{spec.core: spec.automatic})


# --- the .ui file ---------------------------------------------------------------------------------------------------

def test_ui_file_has_a_widget_for_every_parameter_in_its_section():
    sections = ui_sections()
    expected = {"inputsCollapsibleButton": None, **lib_parameters.SECTIONS, **lib_parameters.FIT_SECTIONS}
    assert list(sections) == list(expected)   # the sections, in panel order
    assert not sections["parametersCollapsibleButton"][0], "the main parameters must be visible"
    specs = {spec.name: spec for spec in lib_parameters.parameterSpecs() +
             lib_parameters.parameterSpecs(lib_parameters.FIT_PARAMETERS)}
    for section, (_, rows) in sections.items():
        bound = [properties(widget).get("SlicerParameterName") for _, widget in rows]
        if section == "inputsCollapsibleButton":
            assert [name for name in bound if name] == ["inputNode", "outputModel"]
            continue
        if section == "templateCollapsibleButton":   # the template's node, then its parameters
            assert bound[0] == "templateModel"
            rows, bound = rows[1:], bound[1:]
        assert bound == list(expected[section]), section   # every parameter of the section, in order, no other
        for label, widget in rows:
            name = properties(widget)["SlicerParameterName"]
            spec, own = specs[name], properties(widget)
            assert label is not None and label.get("class") == "QLabel", f"{name} has no label"
            assert properties(label)["text"].endswith(":"), name
            assert widget.get("class") == WIDGET_CLASSES["choices" if spec.choices else spec.kind], name
            # the tooltip (help and unit), the range and the value come from the dataclass, never from the .ui
            assert not {"toolTip", "minimum", "maximum", "value", "text", "currentIndex"} & set(own), name
            if spec.kind in (int, float):
                assert own.get("suffix") == UNIT_SUFFIX[spec.unit], f"{name}: unit {spec.unit!r}"
            if spec.automatic is not None:   # the spin box shows "automatic" at its minimum, the automatic value
                assert own.get("specialValueText", "").startswith("automatic"), name
            if spec.kind is float:   # the default shows as it is
                decimals = int(own.get("decimals", 2))
                assert round(spec.default, decimals) == spec.default, f"{name}: {decimals} decimals"


# --- keywords to the core's parameter objects -----------------------------------------------------------------------

def test_keywords_split_by_dataclass_and_unknown_names_are_refused():
    split = lib_parameters.splitParameters({"min_dihedral": 25.0, "iterations": 3, "margin": 2.0, "rv_wall": 4.0,
                                            "allow_implausible": 1, "handles": "keep", "method": None}, "rbf")
    assert split["OptimizeParameters"] == {"min_dihedral": 25.0, "iterations": 3}
    assert split["ImplicitParameters"] == {"margin": 2.0, "method": "rbf"}
    assert split["LabelledParameters"] == {"rv_wall": 4.0, "allow_implausible": 1}
    assert split["SpuriousParameters"] == {"handles": "keep"}
    assert lib_parameters.splitParameters({"fibres": 1, "alpha_epi": -60.0, "margin": 2.0}, "mpu")[
        "FibreParameters"] == {"fibres": 1, "alpha_epi": -60.0}
    with pytest.raises(InvalidInputError, match=r"unknown parameter\(s\) min_dihedrals; known: .*min_dihedral"):
        lib_parameters.splitParameters({"min_dihedrals": 25.0}, "mpu")
    with pytest.raises(InvalidInputError, match="unknown parameter.* minDihedral"):   # a panel name, not a keyword
        lib_parameters.splitParameters({"minDihedral": 25.0}, "mpu")
    assert lib_parameters.coreParameters({"radius": -1.0, "gridSpacing": 0.5, "method": "rbf", "cells": 500}) == \
        {"radius": None, "grid_spacing": 0.5, "method": "rbf", "cells": 500}
    # 0 is a value, refused by the core where it is outside the range (never "automatic": that is -1)
    assert lib_parameters.coreParameters({"radius": 0.0, "errorBound": 0.0}) == {"radius": 0.0, "error_bound": 0.0}
    assert lib_parameters.coreParameters({"minWall": -1.0, "margin": 0.0, "minDihedral": 25.0, "iterations": 0}) == \
        {"min_wall": None, "margin": 0.0, "min_dihedral": 25.0, "iterations": 0}
    assert lib_parameters.coreParameters({"fibres": True, "alphaEndo": 60.0, "alphaEpi": -60.0, "betaEndo": 0.0,
                                          "betaEpi": -90.0}) == \
        {"fibres": True, "alpha_endo": 60.0, "alpha_epi": -60.0, "beta_endo": 0.0, "beta_epi": -90.0}
    with pytest.raises(InvalidInputError, match="unknown panel parameter.* min_dihedral"):
        lib_parameters.coreParameters({"min_dihedral": 25.0})


def test_settings_hold_the_values_and_the_optimizer_follows_its_switch():
    bounds = {"iterations": 3, "min_dihedral": 25.0, "min_quality": 0.35}
    on = lib_parameters.coreSettings({"optimize": 1, "rv_wall": 4.0, "margin": 2.0, **bounds}, "mpu")
    assert on["OptimizeParameters"] == core.OptimizeParameters(optimize=1, **bounds)
    assert on["LabelledParameters"] == core.LabelledParameters(rv_wall=4.0)
    assert on["ImplicitParameters"] == core.ImplicitParameters(method="mpu", margin=2.0)
    assert lib_parameters.coreSettings({"optimize": 1}, "mpu")["OptimizeParameters"] == \
        core.OptimizeParameters(optimize=1)
    assert lib_parameters.coreSettings(bounds, "mpu")["OptimizeParameters"].optimize == 1   # on (its default)
    # the bounds are checked even when the optimizer is off
    with pytest.raises(InvalidInputError, match=r"min_dihedral must be in \[0, 60\)"):
        lib_parameters.coreSettings({"optimize": 0, "min_dihedral": 60.0}, "mpu")
    with pytest.raises(InvalidInputError, match="iterations"):
        lib_parameters.coreSettings({"optimize": 1, "iterations": -1}, "mpu")


def test_settings_hold_the_fibre_switch_and_angles_and_check_them_when_off():
    assert lib_parameters.coreSettings({}, "mpu")["FibreParameters"] == FibreParameters()   # off by default
    assert FibreParameters().fibres == 0
    angles = {"alpha_endo": 60.0, "alpha_epi": -60.0, "beta_endo": 0.0, "beta_epi": -90.0}
    assert lib_parameters.coreSettings({"fibres": True, **angles}, "mpu")["FibreParameters"] == \
        FibreParameters(fibres=1, **angles)
    with pytest.raises(InvalidInputError, match=r"alpha_endo must be in \[-90, 90\], got 100"):
        lib_parameters.coreSettings({"fibres": 0, "alpha_endo": 100.0}, "mpu")
    with pytest.raises(InvalidInputError, match=r"beta_epi must be in \[-90, 90\]"):
        lib_parameters.coreSettings({"fibres": 1, "beta_epi": -90.5}, "mpu")


# --- the parameter node (BiteMesh.py, with stand-ins for what only the Slicer application has) ------------------------

LOAD_MODULE_FILE = """
import sys, types, typing
sys.modules["qt"] = types.ModuleType("qt")
scripted = types.ModuleType("slicer.ScriptedLoadableModule")
for name in ("ScriptedLoadableModule", "ScriptedLoadableModuleWidget", "ScriptedLoadableModuleTest",
             "ScriptedLoadableModuleLogic"):
    setattr(scripted, name, type(name, (), {"__init__": lambda self, parent=None: setattr(self, "parent", parent)}))
sys.modules["slicer.ScriptedLoadableModule"] = scripted
wrapper = types.ModuleType("slicer.parameterNodeWrapper")
def validator(name):
    return type(name, (), {"__init__": lambda self, *arguments: setattr(self, "arguments", arguments)})
wrapper.Choice, wrapper.Minimum, wrapper.WithinRange = map(validator, ("Choice", "Minimum", "WithinRange"))
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
fields = {}
for name, hint in hints.items():
    kind, *validators = typing.get_args(hint) or (hint,)   # free text: plain str
    if isinstance(kind, type) and kind in (int, float, str, bool):
        fields[name] = (kind.__name__, [(type(v).__name__, v.arguments) for v in validators], getattr(cls, name))
print(repr({"names": sorted(hints), "fields": fields}))
"""


def test_parameter_node_has_each_dataclass_range_and_default():
    """BiteMesh.py builds its parameterNodeWrapper class (the widgets' ranges and values) from the dataclasses."""
    pytest.importorskip("slicer", reason="BiteMesh.py needs slicer-core's slicer and vtk")
    completed = subprocess.run([sys.executable, "-c", LOAD_MODULE_FILE, str(MODULE)], capture_output=True,
                               text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr
    node = ast.literal_eval(completed.stdout.strip().splitlines()[-1])
    assert set(node["names"]) == set(lib_parameters.PARAMETERS) | set(lib_parameters.FIT_PARAMETERS) | {
        "inputNode", "contours", "segmentId", "outputModel", "templateModel"}
    for name in {**lib_parameters.PARAMETERS, **lib_parameters.FIT_PARAMETERS}:
        item, (kind, validators, default) = core_field(name), node["fields"][name]
        if "choices" in item.metadata:
            assert (kind, validators, default) == ("str", [("Choice", (list(item.metadata["choices"]),))],
                                                   item.default), name
            continue
        if item.metadata.get("text"):
            assert (kind, validators, default) == ("str", [], item.default), name
            continue
        low, high, _, _ = item.metadata["range"]
        integer = item.metadata["integer"]
        if integer and (low, high) == (0, 1):   # a switch: a check box
            assert (kind, validators, default) == ("bool", [], bool(item.default)), name
            continue
        assert kind == ("int" if integer else "float"), name
        if item.default is None:   # automatic: a number below the valid range, at the widget's minimum
            assert default == core.AUTOMATIC and default <= low, name
            low = default
        else:
            assert default == item.default, name
        if integer:
            high = INT_MAX if high is None else min(high, INT_MAX)
        expected = ("Minimum", (low,)) if high is None or high == float("inf") else ("WithinRange", (low, high))
        assert validators == [expected], name
    # the fibres, pinned: a check box, off, and the angles' defaults within [-90, 90] degrees
    assert node["fields"]["fibres"] == ("bool", [], False)
    assert {name: node["fields"][name] for name in ("alphaEndo", "alphaEpi", "betaEndo", "betaEpi")} == {
        name: ("float", [("WithinRange", (-90.0, 90.0))], default)
        for name, default in (("alphaEndo", 40.0), ("alphaEpi", -50.0), ("betaEndo", -65.0), ("betaEpi", 25.0))}
