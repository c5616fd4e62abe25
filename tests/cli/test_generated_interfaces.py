"""Every parameter reaches every interface from its dataclass: the ``bitemesh`` flags and the VTK setters (the
ParaView properties are checked under pvbatch in tests/paraview, the Slicer parameters in tests/slicer).

The tables below say which dataclasses each interface carries; a field added to a dataclass must then show up in
each of them with the dataclass's default, and its automatic value must mean None everywhere.
"""
from __future__ import annotations

from dataclasses import fields

import pytest

import bitemesh
from bitemesh import algorithms
from bitemesh.cli import build_parser
from bitemesh.core import parameters as core
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.check import FemParameters
from bitemesh.core.fem.fibres import FibreParameters
from bitemesh.core.fem.template import FitParameters
from bitemesh.core.parameters import AUTOMATIC, is_optional

#: command -> the dataclasses whose every field is a flag of it
MESH_OPTIONS = (core.TableParameters, core.ImplicitParameters, core.BitingParameters, core.SpuriousParameters,
                core.FidelityParameters, core.OptimizeParameters, core.LabelledParameters)
COMMANDS = {
    "mesh": (*MESH_OPTIONS, FibreParameters),
    "batch": MESH_OPTIONS,   # the same options as bitemesh mesh, but --fibres
    "demo": (core.OptimizeParameters, FibreParameters),
    "quality": (core.QualityParameters,),
    "fem": (FemParameters,),
}
#: VTK filter -> the dataclasses whose fields it has setters for, in order ((dataclass, names): those fields only)
FILTERS = {
    "PointsToImplicit": (core.ImplicitParameters, (core.BitingParameters, ("radius", "cells")),
                         core.LabelMapParameters,   # the heart's plausibility check runs in MeshFromPoints only:
                         (core.LabelledParameters, [item.name for item in fields(core.LabelledParameters)
                                                    if item.name != "allow_implausible"])),
    "BitingSampler": (core.BitingParameters,),
    "DelaunayTetra": (),
    "SpuriousCellFilter": (core.SpuriousParameters, core.FidelityParameters),
    "MeshOptimizer": ((core.OptimizeParameters, ("iterations", "min_dihedral", "min_quality")),),   # runs always
    "QualityFilter": (core.QualityParameters,),
    "MeshFromPoints": (core.ImplicitParameters, core.BitingParameters, core.SpuriousParameters,
                       core.OptimizeParameters, core.LabelledParameters,
                       core.FidelityParameters),
    "FibreField": ((FibreParameters, ("alpha_endo", "alpha_epi", "beta_endo", "beta_epi")),),   # runs always
    "TemplateFit": (FitParameters,),
    "VentricularCoordinates": (),
}
#: the arguments a command needs before its flags parse.
REQUIRED = {"mesh": ("in.csv", "-o", "out.vtu"), "batch": ("in.csv", "-o", "out"), "quality": ("m.vtu",),
            "fem": ("m.vtu",)}
DATACLASSES = [value for value in vars(core).values()
               if isinstance(value, type) and issubclass(value, core.Parameters) and value is not core.Parameters]


def expected_fields(specs) -> list:
    return [item for spec in specs for item in fields(spec[0] if isinstance(spec, tuple) else spec)
            if not isinstance(spec, tuple) or item.name in spec[1]]


def camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


@pytest.mark.parametrize("command", COMMANDS)
def test_every_field_is_a_flag_with_the_dataclass_default(command):
    parser = build_parser()._subparsers._group_actions[0].choices[command]
    actions = {option: action for action in parser._actions for option in action.option_strings}
    for item in expected_fields(COMMANDS[command]):
        flag = f"--{item.name.replace('_', '-')}"
        assert flag in actions, f"bitemesh {command}: no flag for {item.name}"
        action = actions[flag]
        assert action.dest == item.name and action.option_strings == [flag]
        assert action.default == item.default, f"bitemesh {command} {flag}: default {action.default!r}"
        assert item.metadata["help"].removeprefix("1 ")[:30] in action.help.replace("%%", "%")
        if item.metadata.get("range", ())[:2] == (0, 1) and item.metadata["integer"]:   # a switch: both ways
            off = parser.parse_args([*REQUIRED.get(command, ()), f"--no-{flag[2:]}"])
            on = parser.parse_args([*REQUIRED.get(command, ()), flag])
            assert (getattr(on, item.name), getattr(off, item.name)) == (1, 0), flag
        if is_optional(item):   # "automatic", as in every interface: -1, or auto
            for text in (str(AUTOMATIC), "auto"):
                assert getattr(parser.parse_args([*REQUIRED.get(command, ()), flag, text]), item.name) is None


def test_every_filter_has_setters_for_exactly_its_fields():
    assert set(FILTERS) == set(bitemesh.FILTERS)
    every = {item.name for specs in FILTERS.values() for item in expected_fields(specs)}
    for name, specs in FILTERS.items():
        algorithm = getattr(algorithms, name)()
        expected = expected_fields(specs)
        assert [item.name for item in type(algorithm).parameter_fields] == [item.name for item in expected], name
        for item in expected:
            assert getattr(algorithm, f"Get{camel(item.name)}")() == item.default, f"{name}.Get{camel(item.name)}"
        for other in every - {item.name for item in expected}:
            assert not hasattr(algorithm, f"Set{camel(other)}"), f"{name} has Set{camel(other)}, which it ignores"


def test_the_automatic_value_means_none_in_every_vtk_setter_and_nothing_else():
    optional = [(name, item) for name, specs in FILTERS.items() for item in expected_fields(specs)
                if is_optional(item)]
    assert {item.name for _, item in optional} >= {"radius", "grid_spacing", "error_bound", "margin", "min_wall"}
    for name, item in optional:
        algorithm = getattr(algorithms, name)()
        setter, getter = getattr(algorithm, f"Set{camel(item.name)}"), getattr(algorithm, f"Get{camel(item.name)}")
        setter(4)
        setter(AUTOMATIC)
        assert getter() is None, f"{name}.Set{camel(item.name)}({AUTOMATIC})"
        owner = next(cls for cls in DATACLASSES if item in fields(cls))
        with pytest.raises(InvalidInputError, match=item.name):   # it can never stand for a real value
            owner(**{item.name: AUTOMATIC})
    # every optional field of every dataclass, also those no filter has (the CLI's, Slicer's): -1 is outside
    for cls in DATACLASSES:
        for item in fields(cls):
            if is_optional(item):
                with pytest.raises(InvalidInputError, match=item.name):
                    cls(**{item.name: AUTOMATIC})
