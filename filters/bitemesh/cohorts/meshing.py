"""One case meshed as ``bitemesh mesh INPUT`` meshes it: the options named like its flags, checked by the same
dataclasses, and the dispatch by kind of input (scattered points, labelled contours, a label map).

``bitemesh mesh`` itself calls :func:`mesh_input`, so that a cohort's case and a single run give the same mesh.
"""
from __future__ import annotations

import difflib
from dataclasses import fields
from pathlib import Path

from ..core.errors import InvalidInputError
from ..core.fem.fibres import FIBRE_ARRAYS, FibreParameters
from ..core.parameters import (AUTOMATIC, STEP_PARAMETERS, LabelledParameters, LabelMapParameters,
                               TableParameters, is_optional)
from ..core.sources.points import run as run_pipeline
from ..core.steps.spine import MeshingResult
from ..io import (LABEL_MAP_EXTENSIONS, NO_CELL_ARRAYS, looks_labelled, read_labelled_config, read_labelled_points,
                  read_points)

#: the parameter dataclasses of ``bitemesh mesh``, in the order its help lists them.
OPTION_CLASSES = (TableParameters, *STEP_PARAMETERS, LabelledParameters, FibreParameters)
#: the options of ``bitemesh mesh`` that are no dataclass field: label map labels, RAS output, a config file.
EXTRA_OPTIONS = {"label": None, "ras": False, "config": None}
OPTION_NAMES = tuple(item.name for cls in OPTION_CLASSES for item in fields(cls)) + tuple(EXTRA_OPTIONS)


def flag(name: str) -> str:
    return f"--{name.replace('_', '-')}"


def default_options() -> dict:
    """Every option of ``bitemesh mesh`` at its default, by name."""
    return {**{item.name: item.default for cls in OPTION_CLASSES for item in fields(cls)}, **EXTRA_OPTIONS}


def check_names(names, where: str = "options") -> None:
    """Refuse a name that is no option of ``bitemesh mesh``, with the closest one."""
    for name in names:
        if name not in OPTION_NAMES:
            close = difflib.get_close_matches(name, OPTION_NAMES, n=1)
            hint = f"did you mean {close[0]} ({flag(close[0])})?" if close else \
                "the options are those of bitemesh mesh: " + ", ".join(OPTION_NAMES)
            raise InvalidInputError(f"{where}: {name!r} is not an option of bitemesh mesh; {hint}")


def resolved(options) -> dict:
    """``options`` (names of ``bitemesh mesh`` flags, with underscores) over the defaults, each value checked by its
    dataclass (range, choices; the message names the parameter, the value and the range)."""
    options = dict(options or {})
    check_names(options)
    full = {**default_options(), **options}
    for cls in OPTION_CLASSES:
        cls(**{item.name: full[item.name] for item in fields(cls)})
    labels = full["label"]
    if labels is not None:
        labels = (labels,) if isinstance(labels, int) else tuple(labels)
        full["label"] = tuple(LabelMapParameters(label=label).label for label in labels) or None
    full["ras"] = bool(full["ras"])
    full["config"] = None if full["config"] in (None, "") else str(full["config"])
    return full


def fibres_asked(options: dict, output) -> FibreParameters | None:
    """The FibreParameters of ``options`` (names of ``bitemesh mesh`` flags; the angles checked) when ``fibres`` is
    on, else None; an ``output`` (path) in a format that keeps no cell arrays is refused, before any work."""
    parameters = FibreParameters(**{item.name: options[item.name] for item in fields(FibreParameters)
                                    if item.name in options})
    if not parameters.fibres:
        return None
    suffix = Path(output).suffix.lower()
    if suffix in NO_CELL_ARRAYS:
        raise InvalidInputError(f"--fibres: a {suffix} file keeps no cell arrays but the regions, so the fibres "
                                f"would be lost; write .vtu or .vtk, which keep {', '.join(FIBRE_ARRAYS)}")
    return parameters


def parse_option(name: str, text: str, where: str = "manifest"):
    """A text value (a manifest cell) of the option ``name``, typed as its ``bitemesh mesh`` flag takes it: a number,
    a choice or text; "auto", -1 or empty for an optional field's automatic value; label: numbers separated by
    spaces or ``;``; ras: 0 or 1."""
    check_names([name], where)
    text = text.strip()
    if name == "config":
        return text or None
    if name in ("label", "ras"):
        try:
            numbers = [int(part) for part in text.replace(";", " ").split()]
        except ValueError:
            raise InvalidInputError(f"{where}: {name} must be whole numbers, got {text!r}") from None
        return (bool(numbers[0]) if numbers else False) if name == "ras" else (tuple(numbers) or None)
    item = next(item for cls in OPTION_CLASSES for item in fields(cls) if item.name == name)
    if "text" in item.metadata or "choices" in item.metadata:
        return text
    if text == "" or (is_optional(item) and text.lower() == "auto"):
        return item.default if not is_optional(item) else None
    try:
        number = float(text)
    except ValueError:
        raise InvalidInputError(f"{where}: {name} ({flag(name)}) must be a number, got {text!r}") from None
    if is_optional(item) and number == AUTOMATIC:
        return None
    return int(number) if item.metadata["integer"] and number == int(number) else number


def mesh_input(path, options, progress=None, mesh_points=run_pipeline) -> MeshingResult:
    """Mesh the file ``path`` as ``bitemesh mesh path`` with the flags ``options`` does (nothing written).

    Parameters
    ----------
    path : a point table, a VTK-readable surface, labelled contours (GPFile, labelled table or VTP) or a label map
    options : mapping of ``bitemesh mesh`` option names (``cells``, ``grid_spacing``, ``label``, ...) to values
    progress : callable(fraction, message), optional
    mesh_points : the function that meshes scattered points (``bitemesh.core.sources.points.run``)
    """
    path = str(path)
    options = {**default_options(), **options}
    table = TableParameters(**{item.name: options[item.name] for item in fields(TableParameters)})
    columns = table.columns or None
    label_map = path.lower().endswith(LABEL_MAP_EXTENSIONS)
    labelled = not label_map and (looks_labelled(path) or (columns and "label" in columns.lower()))
    given = [name for name, on in (("--config", options["config"]), ("--frame", table.frame is not None),
                                   *((flag(name), True) for name in labelled_flags(options))) if on]
    if given and not labelled:
        raise InvalidInputError(
            f"{given[0]} applies to labelled contours, and '{path}' has no label column or Label array (a "
            "biv-me GPFile, a table whose header names a label column, a VTP with a Label point array); leave "
            f"{given[0]} out to mesh the points as one surface")
    if columns and label_map:
        raise InvalidInputError(f"--columns applies to text tables, not to the label map '{path}'")
    steps = dict(zip(("implicit", "biting", "spurious", "optimize", "fidelity"),
                     (cls(**{item.name: options[item.name] for item in fields(cls)}) for cls in STEP_PARAMETERS)))
    if label_map:
        return mesh_label_map(path, options, steps, progress)
    if labelled:
        return mesh_labelled_points(path, options, steps, progress, columns=columns, frame=table.frame)
    return mesh_points(*read_points(path, columns), progress=progress, **steps)


def mesh_label_map(path: str, options: dict, steps: dict, progress) -> MeshingResult:
    from ..labelmap import mesh_label_grid
    from ..io.labelmaps import read_label_map
    label_map = read_label_map(path)
    labels = options["label"]
    return mesh_label_grid(label_map.labels, label_map.index_to_physical(ras=bool(options["ras"])),
                           labels={LabelMapParameters(label=label).label for label in labels} if labels
                           else None, progress=progress, **steps)


def labelled_flags(options: dict) -> dict:
    """The labelled-contour options not at their defaults, as keywords of run_labelled."""
    from ..core.sources.contours.run import labelled_keywords
    parameters = LabelledParameters(**{item.name: options[item.name] for item in fields(LabelledParameters)})
    return labelled_keywords(parameters, given_only=True)


def mesh_labelled_points(path: str, options: dict, steps: dict, progress, columns=None,
                         frame=None) -> MeshingResult:
    """Labelled contour points (time frame ``frame``) to the mesh of the domain of ``domain``; an option given wins
    over the config file."""
    from ..core.sources.contours.run import run_labelled
    points, labels, slices = read_labelled_points(path, columns=columns, frame=frame)
    keywords = read_labelled_config(options["config"]) if options["config"] else {}
    keywords.update(labelled_flags(options))
    return run_labelled(points, labels, slices=slices, progress=progress, **steps, **keywords)
