"""The panel's parameters, read from the core's dataclasses (bitemesh.core.parameters, and FibreParameters of
bitemesh.core.fem.fibres: the single source of names, defaults, ranges and help), and the keywords of
BiteMeshLogic.process turned into the core's parameter objects.

Nothing here imports slicer (only bitemesh), so that the panel can be checked against the dataclasses anywhere.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, fields

#: the panel's sections (the object names of the .ui's collapsible buttons), each with its parameters in panel
#: order: parameter-node name -> (core dataclass, field).  The field name is the keyword of ``process``.
SECTIONS = {
    "parametersCollapsibleButton": {   # "Parameters", open
        "radius": ("BitingParameters", "radius"),
        "cells": ("BitingParameters", "cells"),
        "gridSpacing": ("ImplicitParameters", "grid_spacing"),
        "errorBound": ("ImplicitParameters", "error_bound"),
        "method": ("ImplicitParameters", "method"),
        "threshold": ("SpuriousParameters", "threshold"),
        "optimize": ("OptimizeParameters", "optimize"),
    },
    "contoursCollapsibleButton": {   # "Labelled contours", open
        "domain": ("LabelledParameters", "domain"),
        "basePlane": ("LabelledParameters", "base_plane"),
        "minWall": ("LabelledParameters", "min_wall"),
        "rvWall": ("LabelledParameters", "rv_wall"),
        "allowImplausible": ("LabelledParameters", "allow_implausible"),
        "kernel": ("LabelledParameters", "kernel"),
        "offset": ("LabelledParameters", "offset"),
        "smoothing": ("LabelledParameters", "smoothing"),
        "baseOffset": ("LabelledParameters", "base_offset"),
        "resolution": ("LabelledParameters", "resolution"),
        "sliceShifts": ("LabelledParameters", "slice_shifts"),
    },
    "fibresCollapsibleButton": {   # "Fibres and coordinates (labelled heart contours)", open
        "fibres": ("FibreParameters", "fibres"),
        "alphaEndo": ("FibreParameters", "alpha_endo"),
        "alphaEpi": ("FibreParameters", "alpha_epi"),
        "betaEndo": ("FibreParameters", "beta_endo"),
        "betaEpi": ("FibreParameters", "beta_epi"),
        "coordinates": ("CoordinateParameters", "coordinates"),
    },
    "optimizerCollapsibleButton": {   # "Optimizer", collapsed
        "iterations": ("OptimizeParameters", "iterations"),
        "minDihedral": ("OptimizeParameters", "min_dihedral"),
        "minQuality": ("OptimizeParameters", "min_quality"),
    },
    "advancedCollapsibleButton": {   # "Advanced", collapsed
        "minComponent": ("SpuriousParameters", "min_component"),
        "handles": ("SpuriousParameters", "handles"),
        "order": ("BitingParameters", "order"),
        "seed": ("BitingParameters", "seed"),
        "maxMemoryMb": ("ImplicitParameters", "max_memory_mb"),
        "margin": ("ImplicitParameters", "margin"),
        "outliers": ("ImplicitParameters", "outliers"),
        "bins": ("QualityParameters", "bins"),
        "farSamples": ("FidelityParameters", "far_samples"),
        "unsupportedArea": ("FidelityParameters", "unsupported_area"),
        "allowUnfaithful": ("FidelityParameters", "allow_unfaithful"),
    },
}
#: the module's parameters: parameter-node name -> (core dataclass, field), in panel order.
PARAMETERS = {name: where for section in SECTIONS.values() for name, where in section.items()}
#: the elastic template's section (BiteMeshLogic.fitTemplate, not process), after the others.
FIT_SECTIONS = {"templateCollapsibleButton": {"pull": ("FitParameters", "pull")}}   # "Elastic template", collapsed
FIT_PARAMETERS = {name: where for section in FIT_SECTIONS.values() for name, where in section.items()}
#: the keywords of :meth:`BiteMeshLogic.process` (the core's field names) -> their core dataclass.
KEYWORDS = {fieldName: dataclassName for dataclassName, fieldName in PARAMETERS.values()}
assert len(KEYWORDS) == len(PARAMETERS), "two panel parameters share a core keyword"
#: the module of bitemesh.core holding each panel dataclass that is not in bitemesh.core.parameters.
DATACLASS_MODULES = {"FibreParameters": "bitemesh.core.fem.fibres",
                     "CoordinateParameters": "bitemesh.core.fem.coordinates",
                     "FitParameters": "bitemesh.core.fem.template"}


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of the panel, read from the core's dataclass field.

    Attributes
    ----------
    name : parameter-node name (camelCase); core : keyword of ``process`` (the dataclass field)
    kind : float, int, bool (a 0/1 switch of the core) or str; default : the parameter-node default
    low, high : valid range (None: unbounded); lowOpen : the low bound itself is invalid
    choices : the valid values of a str parameter, else None (a str parameter without choices is free text)
    automatic : the parameter-node value that stands for "chosen automatically" (the core's None), or None when the
        parameter is not optional: bitemesh.core.parameters.AUTOMATIC (-1), never a valid value
    help, unit : from the field's metadata
    """

    name: str
    core: str
    kind: type
    default: object
    low: float | None
    high: float | None
    lowOpen: bool
    choices: tuple | None
    automatic: object
    help: str
    unit: str


def _core():
    """bitemesh.core.parameters, with a useful message when a requirement of bitemesh is missing."""
    from .requirements import requireBitemesh
    requireBitemesh()
    from bitemesh.core import parameters as core
    return core


def coreDataclass(name: str) -> type:
    """The core's parameter dataclass of that name (bitemesh.core.parameters, or the module
    :data:`DATACLASS_MODULES` names for it)."""
    _core()
    return getattr(importlib.import_module(DATACLASS_MODULES.get(name, "bitemesh.core.parameters")), name)


def parameterSpecs(table: dict = PARAMETERS) -> tuple:
    """The :class:`ParameterSpec` of every panel parameter of ``table`` (default: those of ``process``;
    :data:`FIT_PARAMETERS`: the elastic template's), in panel order, from the core's dataclasses."""
    core = _core()
    specs = []
    for name, (dataclassName, fieldName) in table.items():
        item = {f.name: f for f in fields(coreDataclass(dataclassName))}[fieldName]
        metadata = item.metadata
        if "choices" in metadata or metadata.get("text"):
            choices = tuple(metadata["choices"]) if "choices" in metadata else None
            specs.append(ParameterSpec(name, fieldName, str, item.default, None, None, False, choices, None,
                                       metadata["help"], metadata["unit"]))
            continue
        low, high, lowOpen, _ = metadata["range"]
        if metadata["integer"] and (low, high) == (0, 1):   # a switch: a check box, True for 1
            specs.append(ParameterSpec(name, fieldName, bool, bool(item.default), None, None, False, None, None,
                                       metadata["help"], metadata["unit"]))
            continue
        kind = int if metadata["integer"] else float
        high = None if high is None or high == float("inf") else kind(high)
        automatic = None
        default = item.default
        if core.is_optional(item):  # the number that stands for "automatic" (None) in the parameter node
            automatic = default = kind(core.AUTOMATIC)
        specs.append(ParameterSpec(name, fieldName, kind, kind(default), None if low is None else kind(low), high,
                                   bool(lowOpen), None, automatic, metadata["help"], metadata["unit"]))
    return tuple(specs)


def _refuseUnknown(names, known, what: str) -> None:
    from bitemesh.core.errors import InvalidInputError
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise InvalidInputError(f"unknown {what}(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")


def coreParameters(values: dict) -> dict:
    """Parameter-node values (by name) -> keywords of :meth:`BiteMeshLogic.process` ("automatic", -1, becomes
    None); unknown names are refused."""
    specs = {spec.name: spec for spec in parameterSpecs()}
    _refuseUnknown(values, specs, "panel parameter")
    keywords = {}
    for name, value in values.items():
        spec = specs[name]
        keywords[spec.core] = None if spec.automatic is not None and value == spec.automatic else value
    return keywords


def splitParameters(parameters: dict, method: str) -> dict:
    """Split keyword parameters by core dataclass (every dataclass of the panel has an entry, perhaps empty);
    unknown names are refused with the list of known ones.  ``method`` is the default of ImplicitParameters.method
    (also when the keyword is None)."""
    _refuseUnknown(parameters, KEYWORDS, "parameter")
    split = {dataclassName: {} for dataclassName in KEYWORDS.values()}
    for name, value in parameters.items():
        split[KEYWORDS[name]][name] = value
    if split["ImplicitParameters"].get("method") is None:
        split["ImplicitParameters"]["method"] = method
    return split


def coreSettings(parameters: dict, method: str) -> dict:
    """Keyword parameters of :meth:`BiteMeshLogic.process` -> the core's parameter objects, each checked by its
    dataclass: dataclass name -> instance for every dataclass of the panel (OptimizeParameters with its switch,
    ``optimize``, which the core reads; FibreParameters with its switch ``fibres``, which the logic reads)."""
    return {name: coreDataclass(name)(**values) for name, values in splitParameters(parameters, method).items()}
