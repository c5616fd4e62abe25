"""Labelled contour points (a biv-me GPFile, a table with a label column, a VTK file with a Label array) and the
small config file that says which domain to mesh from them."""
from __future__ import annotations


from dataclasses import fields
from pathlib import Path

import numpy as np

from ..core.sources.contours.cardiac import time_frame
from ..core.sources.contours.run import labelled_keywords
from ..core.errors import InvalidInputError, check_points
from ..core.parameters import LabelledParameters
from .files import existing_file, vtk_silenced
from .pointsets import _vtk_reader
from ..core.columns import NAMES, role
from .tables import column_roles, is_number, read_table, split_fields, table_points

LABELLED_TEXT_EXTENSIONS = (".txt", ".csv", ".tsv")
LABELLED_VTK_EXTENSIONS = (".vtp", ".vtk", ".vtu")
LABELLED_EXTENSIONS = LABELLED_TEXT_EXTENSIONS + LABELLED_VTK_EXTENSIONS
#: the names a label column may have (see bitemesh.core.columns).
LABEL_COLUMNS = tuple(name for name, given in NAMES.items() if given == "label")


def read_labelled_points(path, *, columns: str | None = None, frame: float | None = None):
    """Read contour points with a label per point: a biv-me GPFile, a CSV table, or a VTK file with a Label array.

    Parameters
    ----------
    path : str or Path
        ``.txt``, ``.csv``, ``.tsv``: a table, one point per row, fields separated by tabs (a biv-me GPFile:
        header ``x y z contour type frameID weight time frame``), commas, semicolons or spaces.  With a header row,
        the columns are found by name: ``x``, ``y``, ``z`` (else the first three), the label (``label``,
        ``contour type``, ``type``, ``region`` or ``surface``; else the fourth column) and, optionally, the slice
        (``frameID``, ``sliceID`` or ``slice``) and the time frame (``time frame``, ``time``, ``phase``).  Without
        a header: ``x y z label [slice]``.  Labels are strings or integers; ``#`` starts a comment line.
        ``.vtp``, ``.vtk``, ``.vtu``: the points of the dataset and its point-data array ``Label`` (integer or
        string), and optionally ``Slice`` or ``FrameID``.
    columns : comma-separated role of each column of a table (x, y, z, label, slice, frame, skip), e.g.
        "x,y,z,label,skip"; default: from the header's names (see :mod:`bitemesh.io.tables`)
    frame : the time frame to read (a value of the time-frame column); default: every point, which a file whose
        slices are traced at several time frames refuses (a GPFile holds one frame; biv-me writes one file per
        frame, and slices of other series may carry another frame number)

    Returns
    -------
    points : (n, 3) float64, input units
    labels : (n,) str array (integer labels as their decimal text, "1")
    slice_ids : (n,) int64, or None when the file has no slice column or array

    Raises
    ------
    InvalidInputError
        Missing, empty or unreadable file, unknown extension, no label column or array, a malformed row (the
        message names the file and the line), an empty label, no points, several time frames and no ``frame``, or a
        ``frame`` the file does not hold.
    """
    path = existing_file(path, "labelled points", LABELLED_EXTENSIONS)
    frames = None
    if path.suffix.lower() in LABELLED_TEXT_EXTENSIONS:
        points, labels, slice_ids, frames = _read_labelled_table(path, columns)
    elif columns:
        raise InvalidInputError(f"columns applies to text tables, not to '{path}'")
    else:
        points, labels, slice_ids = _read_labelled_vtk(path)
    keep = time_frame(frames, slice_ids, frame, f"'{path}'", "--frame (frame=...)")
    if keep is not None:
        points, labels = points[keep], np.asarray(labels)[keep]
        slice_ids = None if slice_ids is None else slice_ids[keep]
    labels = _label_text(labels)
    empty = labels == ""
    if empty.any():
        raise InvalidInputError(f"cannot read labelled points from '{path}': {int(empty.sum())} points have an "
                                f"empty label (first: point {int(np.argmax(empty))})")
    return points, labels, slice_ids


def looks_labelled(path) -> bool:
    """True when ``path`` holds labelled points for :func:`read_labelled_points`: a table whose header names a
    label column (a GPFile's ``contour type``) or whose first row's fourth field is not a number, or a VTK file
    with a ``Label`` point array.  False for anything else, including unreadable files (let the reader say why)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix in LABELLED_TEXT_EXTENSIONS:
            with open(path, encoding="utf-8-sig", errors="replace") as stream:
                lines = [line for line in (stream.readline() for _ in range(100)) if line.split("#", 1)[0].strip()]
            first = next((i for i, line in enumerate(lines) if is_number(split_fields(line, None)[0].split(",")[0]
                                                                         .split(";")[0], True)), None)
            if first is None:
                return False
            if first:
                header = lines[first - 1]
                return any(role(name) == "label" for mark in ("\t", ";", ",", None)
                           for name in split_fields(header, mark))
            fields = next((split_fields(lines[0], mark) for mark in ("\t", ";", ",") if mark in lines[0]),
                          split_fields(lines[0], None))
            return len(fields) >= 4 and not is_number(fields[3], True)
        if suffix in LABELLED_VTK_EXTENSIONS:
            with vtk_silenced():
                reader = _vtk_reader(path)
                reader.GetExecutive().Update()
                dataset = reader.GetOutputDataObject(0)
            from ..convert import point_labels
            return dataset is not None and hasattr(dataset, "GetPointData") and point_labels(dataset)[0] is not None
    except (OSError, InvalidInputError):
        return False
    return False


def _label_text(labels) -> np.ndarray:
    """Labels as a str array; numbers that are whole ("2", "2.0", 2) become their integer text ("2")."""
    text = np.array([str(label).strip() for label in np.asarray(labels).tolist()], dtype=object)
    try:
        values = np.array([float(label) for label in text])
    except ValueError:
        return text.astype(str)
    if np.isfinite(values).all() and np.all(values == np.round(values)):
        return np.array([str(int(value)) for value in values], dtype=str)
    return text.astype(str)


def _read_labelled_table(path: Path, columns):
    table = read_table(path)
    roles = column_roles(table, columns, labelled=True)
    if "label" not in roles:
        table.fail(f"the header {table.names} names no label column; name it one of {', '.join(LABEL_COLUMNS)}")
    if "z" not in roles:
        table.fail(f"the header {table.names} names no z column: labelled contours are points in 3-D (x y z and "
                   "a label); restore the z column, or name it z")
    points, _ = table_points(table, [role if role in ("x", "y", "z") else "skip" for role in roles])
    labels = table.texts(roles.index("label"))
    slice_ids = None
    if "slice" in roles:
        values = table.numbers(roles.index("slice"), "slice id")
        whole = np.isfinite(values) & (values == np.round(values))
        if not whole.all():
            table.fail(f"line {table.lines[np.argmax(~whole)]} has the slice id "
                       f"{table.rows[np.argmax(~whole)][roles.index('slice')]!r}, not an integer")
        slice_ids = values.astype(np.int64)
    frames = table.numbers(roles.index("frame"), "time frame") if "frame" in roles else None
    if frames is not None and not np.isfinite(frames).all():
        table.fail(f"line {table.lines[np.argmax(~np.isfinite(frames))]} has no number in its time-frame column")
    return check_points(points, f"points of '{path}'", dims=(3,)), labels, slice_ids, frames


def _read_labelled_vtk(path: Path):
    with vtk_silenced():
        reader = _vtk_reader(path)
        succeeded = reader.GetExecutive().Update()
        dataset = reader.GetOutputDataObject(0)
    if not succeeded or reader.GetErrorCode() or dataset is None or not hasattr(dataset, "GetPoints") \
            or dataset.GetPoints() is None or dataset.GetNumberOfPoints() == 0:
        raise InvalidInputError(
            f"cannot read labelled points from '{path}': the {reader.GetClassName()} read no points; is the file "
            "truncated, or not of the format its extension says?")
    from ..convert import point_coordinates, point_labels

    points = check_points(point_coordinates(dataset), f"points of '{path}'", dims=(3,))
    labels, slice_ids = point_labels(dataset, f"cannot read labelled points from '{path}'")
    if labels is None:
        data = dataset.GetPointData()
        present = [data.GetArrayName(i) for i in range(data.GetNumberOfArrays())]
        raise InvalidInputError(
            f"cannot read labelled points from '{path}': it has no one-component point array named 'Label' "
            f"(point arrays present: {', '.join(map(str, present)) or 'none'})")
    return points, labels, slice_ids


#: the keys a labelled-domain config file may hold, with the type each value must have: every field of
#: LabelledParameters (checked by it) and the two mappings.
LABELLED_CONFIG_KEYS = {**{item.name: ("'auto', 'valves', 'none', null or {point: [x, y, z], normal: [x, y, z]}"
                                       if item.name == "base_plane" else "str" if item.type == "str" else "number")
                           for item in fields(LabelledParameters)},
                        "surfaces": "{name: [labels]}", "outlets": "{surface: [valve labels]}"}


def read_labelled_config(path) -> dict:
    """Read a small JSON or TOML file that says which domain to mesh from labelled contours.

    Example (JSON)::

        {"surfaces": {"EPI": ["SAX_LV_EPICARDIAL", "LAX_LV_EPICARDIAL"], "LV_ENDO": ["SAX_LV_ENDOCARDIAL"]},
         "domain": "EPI - LV_ENDO", "base_plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "min_wall": 2.0}

    Keys (all optional): see :data:`LABELLED_CONFIG_KEYS`; they are the keyword arguments of
    :func:`bitemesh.core.labelled.labelled_implicit` and ``run_labelled``.

    Returns
    -------
    dict of those keyword arguments, ``base_plane`` as None, a string or a (point, normal) pair

    Raises
    ------
    InvalidInputError
        Missing or unreadable file, a syntax error (with the parser's message), an unknown key (the message lists
        the known ones) or a value of the wrong type.
    """
    path = existing_file(path, "a labelled-domain config", (".json", ".toml"))
    try:
        text = path.read_text(encoding="utf-8")
        if path.suffix.lower() == ".json":
            import json
            config = json.loads(text)
        else:
            try:
                import tomllib
            except ImportError:   # Python < 3.11
                raise InvalidInputError(f"cannot read '{path}': TOML needs Python 3.11 or later; use JSON") from None
            config = tomllib.loads(text)
    except InvalidInputError:
        raise
    except (OSError, ValueError) as error:
        raise InvalidInputError(f"cannot read a labelled-domain config from '{path}': {error}") from None
    if not isinstance(config, dict):
        raise InvalidInputError(f"'{path}' must hold a table (an object) of settings, got {type(config).__name__}")
    unknown = sorted(set(config) - set(LABELLED_CONFIG_KEYS))
    if unknown:
        raise InvalidInputError(f"'{path}': unknown key(s) {', '.join(unknown)}; known keys: "
                                f"{', '.join(LABELLED_CONFIG_KEYS)}")

    def fail(key):
        raise InvalidInputError(f"'{path}': {key} must be {LABELLED_CONFIG_KEYS[key]}, got {config[key]!r}")

    def label_lists(key):
        value = config[key]
        if not isinstance(value, dict) or not all(
                isinstance(members, (str, int)) or (isinstance(members, list) and members
                                                    and all(isinstance(m, (str, int)) for m in members))
                for members in value.values()):
            fail(key)
        return {str(name): [str(m) for m in (members if isinstance(members, list) else [members])]
                for name, members in value.items()}

    result = {}
    scalars = {}
    for key, value in config.items():
        if key in ("surfaces", "outlets"):
            result[key] = label_lists(key)
        elif key == "base_plane" and isinstance(value, dict):
            if set(value) != {"point", "normal"}:
                fail(key)
            result[key] = (value["point"], value["normal"])
        elif key == "base_plane" and value is None:
            result[key] = None
        elif LABELLED_CONFIG_KEYS[key] == "number" and (isinstance(value, bool) or not isinstance(value, (int, float))):
            fail(key)
        elif (LABELLED_CONFIG_KEYS[key] == "str" or key == "base_plane") and not isinstance(value, str):
            fail(key)
        else:
            scalars[key] = value
    try:
        checked = labelled_keywords(LabelledParameters(**scalars))
    except InvalidInputError as error:
        raise InvalidInputError(f"'{path}': {error}") from None
    result.update({key: checked[key] for key in scalars})
    return result
