"""The one options object of a mesh: every field of the step dataclasses, generated from them, plus the few that
say how to read the input.

The command line, a cohort's manifest, the VTK setters, ParaView and Slicer all build an :class:`Options`;
:func:`bitemesh.mesh` takes it.  Each field keeps its dataclass's default, unit and range (``fields(Options)``
carry the same metadata), and an ``Options`` is checked by those dataclasses when it is made: a bad value is
refused naming the parameter, the value and the range.
"""
from __future__ import annotations

import difflib
from dataclasses import asdict, field, fields, make_dataclass, replace
from typing import Optional

from .core.compiled import check_threads
from .core.errors import InvalidInputError
from .core.fem.coordinates import CoordinateParameters
from .core.fem.fibres import FibreParameters
from .core.sources.spacetime import SpaceTimeParameters
from .core.parameters import (AUTOMATIC, STEP_PARAMETERS, LabelledParameters, LabelMapParameters, TableParameters,
                              is_optional)

#: the parameter dataclasses whose fields an Options holds, in the order ``bitemesh mesh --help`` lists them.
OPTION_CLASSES = (TableParameters, *STEP_PARAMETERS, LabelledParameters, FibreParameters, CoordinateParameters,
                  SpaceTimeParameters)
#: the step each of STEP_PARAMETERS is the parameters of, as the spine's functions name their arguments.
STEP_NAMES = ("implicit", "biting", "spurious", "optimize", "fidelity")
#: the fields that are no dataclass's: how a label map or a labelled-contour file is read.
READING = (
    ("label", Optional[tuple], field(default=None, metadata={
        "help": "label maps: the labels meshed, their union with a region per label; default every nonzero voxel",
        "integer": True})),
    ("ras", bool, field(default=False, metadata={
        "help": "label maps: write the mesh in RAS (3D Slicer) instead of LPS (ITK)"})),
    ("config", Optional[str], field(default=None, metadata={
        "help": "labelled contours: a JSON or TOML file with the domain and its options (options given win)",
        "text": True})),
    ("unit", str, field(default="mm", metadata={
        "help": "the unit of the input's coordinates (and the mesh's), written into the files that hold one: .xdmf, "
                "the cardiac-geometries folder's info.json, the Abaqus .inp; openCARP's micrometres are converted "
                "from it", "choices": ("um", "mm", "cm", "m")})),
)

#: the fields that say how to run, not what: the mesh does not depend on them (left out of a cohort case's hash).
RUNNING = (
    ("threads", Optional[int], field(default=None, metadata={
        "help": "the threads of the parallel kernels, 1 to the machine's cores (the mesh is the same for any "
                "count); default the environment variable BITEMESH_THREADS, else every core; a batch's workers take "
                "1 each unless it is given", "integer": True})),
)


class _Checked:
    """What Options does beyond holding its fields."""

    def __post_init__(self):
        for item in fields(self):   # a GUI's empty text may come as None: the default's empty text
            if "text" in item.metadata and item.default == "" and getattr(self, item.name) is None:
                object.__setattr__(self, item.name, "")
        labels = self.label
        if labels is not None:
            labels = tuple(labels) if isinstance(labels, (tuple, list, set, frozenset)) else (labels,)
            labels = tuple(LabelMapParameters(label=label).label for label in labels) or None
        object.__setattr__(self, "label", labels)
        object.__setattr__(self, "ras", bool(self.ras))
        object.__setattr__(self, "config", None if self.config in (None, "") else str(self.config))
        units = next(item for item in fields(self) if item.name == "unit").metadata["choices"]
        if self.unit not in units:
            raise InvalidInputError(f"unit (--unit) must be one of {', '.join(units)} (the input's coordinates), got "
                                    f"{self.unit!r}")
        if self.threads is not None:
            object.__setattr__(self, "threads", check_threads(self.threads))
        for cls in OPTION_CLASSES:
            self.of(cls)   # each dataclass checks its fields

    def of(self, cls):
        """The parameter dataclass ``cls`` filled from these options."""
        return cls(**{item.name: getattr(self, item.name) for item in fields(cls)})

    @property
    def steps(self) -> dict:
        """The spine's parameters by step: implicit, biting, spurious, optimize, fidelity."""
        return {name: self.of(cls) for name, cls in zip(STEP_NAMES, STEP_PARAMETERS)}

    def given(self, cls=None) -> dict:
        """The options not at their defaults (of ``cls``'s fields only, when given), by name."""
        names = [item.name for item in fields(cls or Options)]
        default = Options()
        return {name: getattr(self, name) for name in names if getattr(self, name) != getattr(default, name)}

    def replace(self, **changes) -> "Options":
        """These options with ``changes`` (names checked, values checked)."""
        check_names(changes)
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return asdict(self)


Options = make_dataclass(
    "Options",
    [(item.name, item.type, field(default=item.default, metadata=item.metadata))
     for cls in OPTION_CLASSES for item in fields(cls)] + list(READING) + list(RUNNING),
    bases=(_Checked,), frozen=True)
Options.__module__ = __name__
Options.__doc__ = ("Every option of a mesh, by the name of its ``bitemesh mesh`` flag (underscores for dashes): the "
                   "fields of " + ", ".join(cls.__name__ for cls in OPTION_CLASSES) + ", and label, ras, config, unit, "
                   "threads. "
                   "None for an optional number is automatic.")
#: every option's name.
OPTION_NAMES = tuple(item.name for item in fields(Options))


def flag(name: str) -> str:
    return f"--{name.replace('_', '-')}"


def check_names(names, where: str = "options") -> None:
    """Refuse a name that is no option, with the closest one."""
    for name in names:
        if name not in OPTION_NAMES:
            close = difflib.get_close_matches(name, OPTION_NAMES, n=1)
            hint = f"did you mean {close[0]} ({flag(close[0])})?" if close else \
                "the options are those of bitemesh mesh: " + ", ".join(OPTION_NAMES)
            raise InvalidInputError(f"{where}: {name!r} is not an option of bitemesh mesh; {hint}")


def as_options(options=None, **changes) -> Options:
    """``options`` (an Options, a mapping of option names to values, or None for the defaults) with ``changes``;
    every name and value checked."""
    if options is None or isinstance(options, dict):
        options = dict(options or {})
        check_names(options)
        options = Options(**options)
    elif not isinstance(options, Options):
        raise InvalidInputError(f"options must be bitemesh.Options or a dict of option names, got "
                                f"{type(options).__name__}")
    return options.replace(**changes) if changes else options


def parse_option(name: str, text: str, where: str = "manifest"):
    """A text value (a manifest cell, a ``--set name=value``) of the option ``name``, typed as its flag takes it: a
    number, a choice or text; "auto", -1 or empty for an optional field's automatic value; label: numbers
    separated by spaces or ``;``; ras: 0 or 1."""
    check_names([name], where)
    text = text.strip()
    item = next(item for item in fields(Options) if item.name == name)
    if name in ("label", "ras"):
        try:
            numbers = [int(part) for part in text.replace(";", " ").split()]
        except ValueError:
            raise InvalidInputError(f"{where}: {name} must be whole numbers, got {text!r}") from None
        return (bool(numbers[0]) if numbers else False) if name == "ras" else (tuple(numbers) or None)
    if "text" in item.metadata or "choices" in item.metadata:
        return text or (None if item.default is None else text)
    if text == "" or (is_optional(item) and text.lower() == "auto"):
        return item.default
    try:
        number = float(text)
    except ValueError:
        raise InvalidInputError(f"{where}: {name} ({flag(name)}) must be a number, got {text!r}") from None
    if is_optional(item) and number == AUTOMATIC:
        return None
    return int(number) if item.metadata["integer"] and number == int(number) else number

