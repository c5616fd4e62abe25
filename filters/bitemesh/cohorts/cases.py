"""The cases of a cohort: found from files, folders, glob patterns or a manifest CSV; their hash (input and
parameters) and the record each finished case leaves beside the meshes, by which a rerun skips it."""
from __future__ import annotations

import csv
import glob
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..core.errors import InvalidInputError
from ..io import MESH_EXTENSIONS, atomic_output
from ..meshing import INPUT_EXTENSIONS
from ..options import RUNNING, as_options, check_names, parse_option

#: the files a folder or a glob pattern gives as cases
#: the manifest's columns that are no option: the input file and the output's name
MANIFEST_COLUMNS = ("input", "output")
#: the folder of OUTDIR holding each finished case's record (hash, summary row) and picture
RECORDS = ".bitemesh"


@dataclass(frozen=True)
class Case:
    """One input meshed to ``OUTDIR/name + extension``, with its own options over the cohort's."""

    name: str
    input: Path
    options: dict = field(default_factory=dict)
    extension: str = ".vtu"

    @property
    def output_name(self) -> str:
        return self.name + self.extension


def stem(path: Path) -> str:
    """The file's name without its extension (``seg.nii.gz`` -> ``seg``)."""
    name = path.name
    for extension in sorted(INPUT_EXTENSIONS, key=len, reverse=True):
        if name.lower().endswith(extension):
            return name[:-len(extension)]
    return path.stem


def is_manifest(path: Path) -> bool:
    """A .csv whose header's first column is ``input``."""
    if path.suffix.lower() != ".csv" or not path.is_file():
        return False
    with open(path, newline="") as stream:
        header = next(csv.reader(stream), [])
    return bool(header) and header[0].strip().lower() == "input"


def find_cases(inputs, extension: str = ".vtu") -> list:
    """The cases of ``inputs``: :class:`Case` objects, files, folders (their input files, sorted), glob patterns or
    manifest CSVs; each named by its file's stem (or the manifest's output column).  Refuses a missing input and
    two cases of the same name."""
    if not str(extension).lower().startswith(".") or str(extension).lower() not in MESH_EXTENSIONS:
        raise InvalidInputError(f"output format {extension!r} is not one bitemesh writes; use one of "
                                f"{', '.join(MESH_EXTENSIONS)}")
    cases = []
    for item in [inputs] if isinstance(inputs, (str, Path, Case)) else inputs:
        if isinstance(item, Case):
            cases.append(item)
            continue
        path = Path(item)
        if is_manifest(path):
            cases += read_manifest(path, extension)
        elif path.is_dir():
            cases += [Case(stem(file), file, extension=extension) for file in sorted(path.iterdir())
                      if file.is_file() and file.name.lower().endswith(INPUT_EXTENSIONS)]
        elif path.exists():
            cases.append(Case(stem(path), path, extension=extension))
        elif glob.has_magic(str(item)):
            matches = [Path(match) for match in sorted(glob.glob(str(item)))]
            cases += [Case(stem(file), file, extension=extension) for file in matches
                      if file.is_file() and file.name.lower().endswith(INPUT_EXTENSIONS)]
        else:
            raise InvalidInputError(f"input '{item}' does not exist (give files, folders, glob patterns or a "
                                    "manifest CSV whose first column is 'input')")
    seen = {}
    for case in cases:
        if case.output_name in seen:
            raise InvalidInputError(f"two cases would write {case.output_name}: '{seen[case.output_name]}' and "
                                    f"'{case.input}'; name them in a manifest's output column")
        seen[case.output_name] = case.input
    return cases


def read_manifest(path: Path, extension: str = ".vtu") -> list:
    """The cases of a manifest CSV: a header ``input[,output][,option...]``, one row per case; inputs relative to
    the manifest's folder; each option column named like a ``bitemesh mesh`` flag (``cells``, ``grid_spacing`` or
    ``grid-spacing``), an empty cell leaving the cohort's value."""
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    header = [name.strip().lower().replace("-", "_") for name in rows[0]]
    options = [name for name in header if name not in MANIFEST_COLUMNS]
    check_names(options, f"manifest {path.name}")   # a misspelt column is refused before any row
    cases = []
    for number, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        where = f"manifest {path.name}, line {number}"
        if len(row) != len(header):
            raise InvalidInputError(f"{where}: {len(row)} cells for {len(header)} columns ({', '.join(header)})")
        cells = dict(zip(header, row))
        source = Path(cells["input"].strip())
        source = source if source.is_absolute() else path.parent / source
        name = cells.get("output", "").strip() or stem(source)
        own = extension
        for known in MESH_EXTENSIONS:
            if name.lower().endswith(known):
                name, own = name[:-len(known)], known
        if not name or Path(name).name != name:
            raise InvalidInputError(f"{where}: output {cells.get('output')!r} must be a file name without a folder")
        given = {option: parse_option(option, cells[option], f"{where}, column {option!r}") for option in options
                 if cells[option].strip()}
        try:
            as_options(given)
        except InvalidInputError as error:
            raise InvalidInputError(f"{where}: {error}") from None
        cases.append(Case(name, source, given, own))
    return cases


def file_digest(path, digest) -> None:
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)


def case_hash(case: Case, options: dict, fitting: dict | None = None) -> str:
    """sha256 of the input file, the config file if any, every option's value (defaults filled), the template file
    and the pull of a fitted cohort (``fitting``: ``{"template": path, "pull": float}``) and the bitemesh version:
    the same hash means the same mesh."""
    digest = hashlib.sha256(f"bitemesh {__version__}\n".encode())
    full = as_options({**options, **case.options}).as_dict()
    for name, *_ in RUNNING:   # how it runs, not what it makes
        del full[name]
    digest.update(json.dumps(full, sort_keys=True, default=str).encode())
    digest.update(case.extension.encode())
    file_digest(case.input, digest)
    if full["config"]:
        file_digest(full["config"], digest)
    if fitting is not None:
        digest.update(f"fitted with pull {fitting['pull']!r}\n".encode())
        file_digest(fitting["template"], digest)
    return digest.hexdigest()


def record_path(output_dir: Path, case: Case) -> Path:
    return Path(output_dir) / RECORDS / f"{case.name}.json"


def write_record(output_dir: Path, case: Case, digest: str, row: dict) -> None:
    """Remember that ``case`` was meshed to its output with the hash ``digest`` (written atomically, after the
    mesh)."""
    path = record_path(output_dir, case)
    path.parent.mkdir(exist_ok=True)
    with atomic_output(path, "a case record") as temporary:
        temporary.write_text(json.dumps({"hash": digest, "row": row}, indent=1))


def recorded_row(output_dir: Path, case: Case, digest: str):
    """The summary row of ``case`` when its output exists and its record has the hash ``digest``, else None."""
    path = record_path(output_dir, case)
    if not (Path(output_dir) / case.output_name).is_file() or not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record["row"] if record.get("hash") == digest else None
