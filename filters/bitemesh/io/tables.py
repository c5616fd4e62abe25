"""Text tables of points (``.xyz``, ``.txt``, ``.csv``, ``.tsv``): which column is what, and how numbers are written.

Columns.  A header row names them (case and units in brackets ignored): ``x y z`` (also ``pos_x``, ``point_x``),
normals ``nx ny nz`` (also ``normal_x``), a label (``label``, ``contour type``, ...), a slice id (``frameID``,
``sliceID``, ``slice``); colours, intensities, weights and times are read past, with a note.  ``columns`` (the CLI's
``--columns x,y,z,skip,nx,ny,nz``) says it instead, and wins.  Without either, the count decides: 2 (x y), 3
(x y z), 4 (x y nx ny) or 6 (x y z nx ny nz), where the last columns are normals only when they are unit vectors
(colour columns ``r g b`` are not, and are refused with the hint to say ``--columns``).  ``dimension`` (the CLI's
``--dimension``, 2 to 5) reads the first k columns as the point and the next k, when there, as its normal: points
of 4 or 5 coordinates (axes x y z w v) are read that way or by ``--columns``.

Numbers.  Fields are separated by tabs, semicolons, commas or spaces; a decimal comma (``120,573;-31,473``, as
European spreadsheets write) is read as a decimal point when the separator is a tab, a semicolon or a space, and
a field that mixes both marks (``1.000,5``) is refused.  ``#`` starts a comment; line numbers in messages count
from 1, as an editor does.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.columns import AXES, KNOWN_OTHERS, ROLES, normalised, role
from ..core.errors import InvalidInputError
from .files import logger

#: the point counts of the columns without a header: 2D or 3D, with or without normals.
WIDTHS = {2: ("x", "y"), 3: ("x", "y", "z"), 4: ("x", "y", "nx", "ny"), 6: ("x", "y", "z", "nx", "ny", "nz")}
#: columns without a header are normals when their rows' lengths are within this of 1 (values printed with 3
#: decimals are within 0.003).
UNIT_TOLERANCE = 0.01
#: a file is binary, not a table, when its first BINARY_PROBE characters hold a NUL or more than BINARY_SHARE of
#: bytes that are not UTF-8 text (a Latin-1 header's accents stay well below it).
BINARY_PROBE, BINARY_SHARE = 65536, 0.05

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf|infinity)$", re.IGNORECASE)
_COMMA_NUMBER = re.compile(r"^[+-]?\d+(,\d+)?([eE][+-]?\d+)?$")


@dataclass(frozen=True)
class Table:
    """The rows of a text table, split into fields (strings), with their line numbers.

    Attributes
    ----------
    path : the file; names : the header's fields, or None; rows : list of lists of fields; lines : (n,) int, the
    line number (from 1) of each row; separator : the field separator (None: whitespace); decimal_comma : bool
    """

    path: Path
    names: list | None
    rows: list
    lines: np.ndarray
    separator: str | None
    decimal_comma: bool

    @property
    def width(self) -> int:
        return len(self.rows[0])

    def fail(self, message: str):
        raise InvalidInputError(f"cannot read points from '{self.path}': {message}")

    def numbers(self, column: int, what: str) -> np.ndarray:
        """(n,) float64 of one column; names the first line whose field is not a number."""
        text = [row[column] for row in self.rows]
        if self.decimal_comma:
            text = [field.replace(",", ".") for field in text]
        try:
            return np.array(text, dtype=np.float64)
        except ValueError:
            bad = next(i for i, field in enumerate(text) if not _NUMBER.match(field))
            self.fail(f"line {self.lines[bad]} has the non-numeric {what} {self.rows[bad][column]!r}; after the header "
                      "every row must hold numbers there")

    def texts(self, column: int) -> list:
        return [row[column] for row in self.rows]


def is_number(field: str, decimal_comma: bool = False) -> bool:
    return bool((_COMMA_NUMBER if decimal_comma else _NUMBER).match(field)) or bool(_NUMBER.match(field))


def _dialect(line: str, path: Path):
    """(separator, decimal_comma) of a data row."""
    stripped = line.split("#", 1)[0].strip()
    for separator in ("\t", ";"):
        if separator in stripped:
            return separator, _decimal_comma([field.strip() for field in stripped.split(separator)], line, path)
    if "," not in stripped:
        return None, False
    spaced = stripped.split()
    if len(spaced) > 1 and "." not in stripped and all(_COMMA_NUMBER.match(field) for field in spaced[:3]):
        return None, True   # "120,5 -31,4 89,9": spaces between the fields, commas inside them
    return ",", False


def _decimal_comma(fields, line: str, path: Path) -> bool:
    commas = [field for field in fields if "," in field]
    if not commas:
        return False
    mixed = [field for field in commas if "." in field]
    if mixed:
        raise InvalidInputError(
            f"cannot read points from '{path}': the field {mixed[0]!r} has both a decimal point and a comma (a "
            "thousands separator?); write numbers without thousands separators, with one decimal mark")
    if not all(_COMMA_NUMBER.match(field) for field in commas if any(c.isdigit() for c in field)):
        raise InvalidInputError(f"cannot read points from '{path}': cannot tell how the numbers of {line.strip()!r} "
                                "are written; use a decimal point and separate fields by tabs, commas or spaces")
    return True


def _is_data(line: str, path: Path) -> bool:
    """True for a row of data: at least two fields, and at least half of them, are numbers."""
    try:
        separator, decimal_comma = _dialect(line, path)
    except InvalidInputError:
        return True   # numbers written in a way that read_table then explains
    fields = split_fields(line, separator)
    numbers = sum(is_number(field, decimal_comma) for field in fields)
    return numbers >= max(2, len(fields) / 2)


def split_fields(line: str, separator) -> list:
    body = line.split("#", 1)[0]
    return [field.strip() for field in body.split(separator)] if separator else body.split()


def read_table(path: Path) -> Table:
    """The table in ``path``: header (the last non-comment line before the first row whose first field is a
    number), rows and their line numbers, separator and decimal mark (see the module docstring)."""
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise InvalidInputError(f"cannot read points from '{path}': {error.strerror or error}") from None
    text = raw.decode("utf-8-sig", errors="replace")
    head = text[:BINARY_PROBE]
    if "\x00" in head or head.count("\ufffd") > BINARY_SHARE * len(head):
        raise InvalidInputError(
            f"cannot read points from '{path}': it is not a text table (it holds binary data: NUL bytes or bytes "
            "that are no text); a point table is text, x y z per line; a binary mesh or point cloud needs its "
            "format's extension (.vtp, .vtu, .vtk, .ply, .stl, .obj)")
    numbered = [(number, line) for number, line in enumerate(text.splitlines(), start=1)
                if line.split("#", 1)[0].strip()]
    if not numbered:
        raise InvalidInputError(f"cannot read points from '{path}': the file holds no rows (only blank lines or "
                                "comments)")
    start = next((i for i, (_, line) in enumerate(numbered) if _is_data(line, path)), None)
    if start is None:
        number, line = numbered[0]
        if len(numbered) == 1:
            raise InvalidInputError(f"cannot read points from '{path}': the file has a header but no points")
        raise InvalidInputError(f"cannot read points from '{path}': no row holds numbers (no points); line "
                                f"{number} is {line.strip()[:60]!r}")
    separator, decimal_comma = _dialect(numbered[start][1], path)
    names = None
    if start:
        header = numbered[start - 1][1]
        names = next((fields for mark in ("\t", ";", ",", None) for fields in [split_fields(header, mark)]
                      if len(fields) > 1 and (mark is None or mark in header)), split_fields(header, None))
        if start > 1:
            logger.info("'%s': %d lines before the header skipped", path.name, start - 1)
    rows, lines = [], []
    for number, line in numbered[start:]:
        rows.append(split_fields(line, separator))
        lines.append(number)
    widths = {len(row) for row in rows}
    if len(widths) > 1:
        first = len(rows[0])
        bad = next(i for i, row in enumerate(rows) if len(row) != first)
        raise InvalidInputError(
            f"cannot read points from '{path}': line {lines[bad]} has {len(rows[bad])} columns but line {lines[0]} "
            f"has {first}; every row must have the same number of columns")
    if decimal_comma:
        logger.info("'%s': numbers read with a decimal comma", path.name)
    return Table(path, names, rows, np.array(lines), separator, decimal_comma)


def column_roles(table: Table, columns: str | None = None, *, labelled: bool = False, dimension=None) -> list:
    """The role (:data:`ROLES`) of each column of ``table``: from ``columns`` (comma-separated roles, one per
    column), else from ``dimension`` (k coordinates, then k normal components when there), else from the header's
    names, else from the column count; refuse what cannot be told."""
    if columns and dimension:
        raise InvalidInputError(f"columns ({columns!r}) and dimension ({dimension}) both say what the columns are; "
                                "give one (--columns x,y,z,w names a 4-D point's columns)")
    if dimension:
        if table.width not in (dimension, 2 * dimension):
            fits = [k for k in range(2, len(AXES) + 1) if table.width in (k, 2 * k)]
            table.fail(f"line {table.lines[0]} has {table.width} columns; dimension {dimension} reads {dimension} "
                       f"(the point) or {2 * dimension} (the point and its normal); "
                       + (f"--dimension {' or '.join(map(str, fits))} reads {table.width}, or " if fits else "")
                       + f"say which column is which with --columns (e.g. --columns "
                       f"{','.join([*AXES[:dimension], *['skip'] * max(table.width - dimension, 0)])})")
        if table.names is not None:
            logger.info("'%s': dimension %d: the header %s not used", table.path.name, dimension, table.names)
        axes = list(AXES[:dimension])
        return axes + ([f"n{axis}" for axis in axes] if table.width == 2 * dimension else [])
    if columns:
        roles = [given.strip().lower() for given in str(columns).split(",")]
        unknown = [given for given in roles if given not in ROLES]
        if unknown:
            raise InvalidInputError(f"columns: unknown role {unknown[0]!r} in {columns!r}; each column is one of "
                                    f"{', '.join(ROLES)}")
        if len(roles) != table.width:
            raise InvalidInputError(f"columns: {columns!r} names {len(roles)} columns, but '{table.path}' has "
                                    f"{table.width} (line {table.lines[0]})")
        return _checked(roles, table, f"columns {columns!r}")
    if table.names is not None and len(table.names) == table.width:
        keys = [normalised(name) for name in table.names]
        roles = [role(name) for name in table.names]
        if not {"x", "y"} <= set(roles):
            table.fail(f"the header {table.names} names no x and y columns; name them x, y, z or say which column "
                       "is which with --columns (e.g. --columns x,y,z,skip)")
        unused = ("skip",) if labelled else ("skip", "frame")   # a time column means nothing to a point set
        skipped = [name for name, given in zip(table.names, roles) if given in unused]
        if skipped:
            unknown = [name for name in skipped if normalised(name) not in KNOWN_OTHERS and role(name) == "skip"]
            logger.info("'%s': columns %s not used%s", table.path.name, ", ".join(skipped),
                        f" ({', '.join(unknown)} not a known column name)" if unknown else "")
        contours = "slice" in roles or {"weight", "time"} <= set(keys)
        if not labelled and "label" not in roles and contours:
            table.fail(f"its header {table.names} is that of labelled contours (a biv-me GPFile: slice, weight, "
                       "time) but it has no label column ('contour type'); the contours of several surfaces cannot "
                       "be meshed as one point set: restore the label column, or say --columns to mesh them anyway")
        return _checked(roles, table, f"the header {table.names}")
    if table.names is not None:
        logger.info("'%s': the header %s has %d names for %d columns; columns told by their count",
                    table.path.name, table.names, len(table.names), table.width)
    if labelled:
        if table.width < 4:
            table.fail(f"line {table.lines[0]} has {table.width} fields; a labelled point needs x y z label [slice] "
                       "(or a header naming the columns)")
        return ["x", "y", "z", "label"] + (["slice"] if table.width > 4 else []) + ["skip"] * (table.width - 5)
    text = [number for number, field in enumerate(table.rows[0]) if field.strip() and not is_number(field, True)]
    if text:   # a label where a coordinate belongs: labelled contours read the label from the fourth column
        fix = ("a coordinate column is missing before it (a GPFile without its z column?); restore it" if text[0] < 3
               else "say which column is which with --columns")
        table.fail(f"column {text[0] + 1} of line {table.lines[0]} holds text ({table.rows[0][text[0]]!r}) where a "
                   f"number belongs, and labelled points carry their label in column 4 (x y z label ...): {fix}, or "
                   "give a header naming the columns (x, y, z, label, ...)")
    if table.width not in WIDTHS:
        table.fail(f"line {table.lines[0]} has {table.width} columns; expected 2 (x y), 3 (x y z), 4 (x y nx ny) or "
                   "6 (x y z nx ny nz), or a header naming the columns, or --columns (e.g. "
                   f"--columns {','.join(['x', 'y', 'z'] + ['skip'] * max(table.width - 3, 0))})")
    roles = list(WIDTHS[table.width])
    if "nx" in roles:
        dim = len(roles) // 2
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # a NaN is named by its line in table_points
            values = np.column_stack([table.numbers(i, "value") for i in range(dim, 2 * dim)])
        lengths = np.linalg.norm(values, axis=1)
        off = np.isfinite(lengths) & (np.abs(lengths - 1) > UNIT_TOLERANCE)
        if off.any() and dim == 2:   # x y z and a value (an intensity) far more often than 2-D points with normals
            logger.info("'%s': 4 columns without a header, the last two no unit vectors: read as x y z and a value "
                        "(column 4 not used); --columns x,y,nx,ny for 2-D points with normals of any length",
                        table.path.name)
            return ["x", "y", "z", "skip"]
        if off.any():
            bad = int(np.argmax(off))
            points = ",".join("xyz"[:dim])
            table.fail(
                f"it has {table.width} columns and no header, and columns {dim + 1}-{2 * dim} are not unit vectors "
                f"(line {table.lines[bad]}: {' '.join(table.rows[bad][dim:])}, length {lengths[bad]:.3g}), so they "
                f"are not normals (colours?); say which column is which: --columns {points},{','.join(['skip'] * dim)} "
                f"(points only) or --columns {points},{','.join(['nx', 'ny', 'nz'][:dim])} (normals of any length)")
        logger.info("'%s': %d columns without a header; the last %d are unit vectors, read as normals",
                    table.path.name, table.width, dim)
    return roles


def _checked(roles: list, table: Table, where: str) -> list:
    for given in ROLES[:-1]:
        if roles.count(given) > 1:
            raise InvalidInputError(f"cannot read points from '{table.path}': {where} gives {given} twice")
    axes = [axis for axis in AXES if axis in roles]
    if axes != list(AXES[:len(axes)]):
        raise InvalidInputError(f"cannot read points from '{table.path}': {where} gives the axes {', '.join(axes)}; "
                                f"a point's axes are {', '.join(AXES[:len(axes)])} (in that order, x y z w v)")
    normals = [given for given in roles if given.startswith("n")]
    if normals and sorted(normals) != sorted(f"n{axis}" for axis in axes):
        raise InvalidInputError(f"cannot read points from '{table.path}': {where} gives the normal columns "
                                f"{', '.join(normals)}; give all of {', '.join(f'n{axis}' for axis in axes)} or none")
    return roles


def table_points(table: Table, roles: list):
    """(points (n, k), normals (n, k) or None) from the columns of ``roles``; every value must be finite."""
    axes = [axis for axis in AXES if axis in roles]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points = np.column_stack([table.numbers(roles.index(axis), "coordinate") for axis in axes])
        normals = None
        if "nx" in roles:
            normals = np.column_stack([table.numbers(roles.index(f"n{axis}"), "normal") for axis in axes])
    for values, what in ((points, "coordinates"), (normals, "normals")):
        if values is not None:
            bad = ~np.isfinite(values).all(axis=1)
            if bad.any():
                table.fail(f"line {table.lines[np.argmax(bad)]} has NaN or infinite {what} ({int(bad.sum())} "
                           f"row{'s' if bad.sum() > 1 else ''} in all); remove {'them' if bad.sum() > 1 else 'it'}")
    return points, normals
