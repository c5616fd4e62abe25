"""The panel's parameters, read from bitemesh.core.parameters (the single source of names, defaults, ranges and
help), and the keywords of BiteMeshLogic.process split by dataclass."""
from __future__ import annotations

from dataclasses import dataclass, fields

from .requirements import requireBitemesh

#: the module's parameters: parameter-node name -> (core dataclass, field), in panel order.
PARAMETERS = {
    "radius": ("BitingParameters", "radius"),
    "cells": ("BitingParameters", "cells"),
    "gridSpacing": ("ImplicitParameters", "grid_spacing"),
    "errorBound": ("ImplicitParameters", "error_bound"),
    "method": ("ImplicitParameters", "method"),
    "threshold": ("SpuriousParameters", "threshold"),
    "minComponent": ("SpuriousParameters", "min_component"),
    "order": ("BitingParameters", "order"),
    "seed": ("BitingParameters", "seed"),
    "maxMemoryMb": ("ImplicitParameters", "max_memory_mb"),
    "bins": ("QualityParameters", "bins"),
    "optimize": ("OptimizeSwitch", "optimize"),
    "domain": ("LabelledParameters", "domain"),
    "basePlane": ("LabelledParameters", "base_plane"),
    "outliers": ("ImplicitParameters", "outliers"),
    "allowUnfaithful": ("FidelityParameters", "allow_unfaithful"),
}
#: keywords of :meth:`BiteMeshLogic.process` that the panel has no widget for (scripts can give them).
EXTRA_KEYWORDS = {"margin": ("ImplicitParameters", "margin"), "min_wall": ("LabelledParameters", "min_wall"),
                  "rv_wall": ("LabelledParameters", "rv_wall"),
                  "allow_implausible": ("LabelledParameters", "allow_implausible")}


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of the panel, read from the core's dataclass field.

    Attributes
    ----------
    name : parameter-node name (camelCase); core : keyword of ``process`` (the dataclass field)
    kind : float, int or str; default : the parameter-node default
    low, high : valid range (None: unbounded); lowOpen : the low bound itself is invalid
    choices : the valid values of a str parameter, else None (a str parameter without choices is free text)
    automatic : the parameter-node value that stands for "chosen automatically" (the core's None), or None when the
        parameter is not optional: bitemesh.core.parameters.automatic_value, 0 or -1, never a valid value
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


def parameterSpecs() -> tuple:
    """The :class:`ParameterSpec` of every panel parameter, in panel order, from bitemesh.core.parameters."""
    requireBitemesh()
    from bitemesh.core import parameters as core
    specs = []
    for name, (dataclassName, fieldName) in PARAMETERS.items():
        item = {f.name: f for f in fields(getattr(core, dataclassName))}[fieldName]
        metadata = item.metadata
        if "choices" in metadata or metadata.get("text"):
            choices = tuple(metadata["choices"]) if "choices" in metadata else None
            specs.append(ParameterSpec(name, fieldName, str, item.default, None, None, False, choices, None,
                                       metadata["help"], metadata["unit"]))
            continue
        low, high, lowOpen, _ = metadata["range"]
        kind = int if metadata["integer"] else float
        high = None if high is None or high == float("inf") else kind(high)
        automatic = None
        default = item.default
        if core.is_optional(item):  # the number that stands for "automatic" (None) in the parameter node
            automatic = default = kind(core.automatic_value(item))
        specs.append(ParameterSpec(name, fieldName, kind, kind(default), None if low is None else kind(low), high,
                                   bool(lowOpen), None, automatic, metadata["help"], metadata["unit"]))
    return tuple(specs)


def coreParameters(values: dict) -> dict:
    """Parameter-node values (by name) -> keywords of :meth:`BiteMeshLogic.process` ("automatic" becomes None)."""
    keywords = {}
    for spec in parameterSpecs():
        if spec.name in values:
            value = values[spec.name]
            keywords[spec.core] = None if spec.automatic is not None and value == spec.automatic else value
    return keywords


def splitParameters(parameters: dict, method: str) -> dict:
    """Split keyword parameters by core dataclass; unknown names are refused with the list of known ones."""
    from bitemesh.core.errors import InvalidInputError
    known = {fieldName: dataclassName for dataclassName, fieldName in
             list(PARAMETERS.values()) + list(EXTRA_KEYWORDS.values())}
    unknown = sorted(set(parameters) - set(known))
    if unknown:
        raise InvalidInputError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    split = {name: {} for name in ("ImplicitParameters", "BitingParameters", "SpuriousParameters",
                                   "QualityParameters", "OptimizeSwitch", "LabelledParameters",
                                   "FidelityParameters")}
    split["ImplicitParameters"]["method"] = method
    for name, value in parameters.items():
        split[known[name]][name] = value
    if split["ImplicitParameters"]["method"] is None:
        split["ImplicitParameters"]["method"] = method
    return split

