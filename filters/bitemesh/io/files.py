"""What every reader and writer shares: checking an input file, writing an output atomically, keeping VTK and
meshio from printing.

VTK is imported lazily, from ``vtkmodules.*`` only, so that this package loads in ParaView 5.11 and Slicer.
"""
from __future__ import annotations

import contextlib
import io as _stdio
import logging
import os
import secrets
import signal
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError

#: notes on what a reader did with a file (columns ignored, a volume mesh's boundary taken) go to this logger.
logger = logging.getLogger("bitemesh")


def supported(extensions) -> str:
    return ", ".join(extensions)


def existing_file(path, what: str, extensions) -> Path:
    """``path`` as a Path after checking that it is a readable, non-empty file with a known extension."""
    path = Path(path)
    name = path.name.lower()
    if not any(name.endswith(extension) for extension in extensions):
        raise InvalidInputError(
            f"cannot read {what} from '{path}': unknown extension {path.suffix or '(none)'!r}; "
            f"supported extensions: {supported(extensions)}")
    if not path.exists():
        raise InvalidInputError(f"cannot read {what} from '{path}': the file does not exist")
    if not path.is_file():
        raise InvalidInputError(f"cannot read {what} from '{path}': it is not a regular file")
    try:
        with open(path, "rb") as stream:
            empty = not stream.read(1)
    except OSError as error:
        raise InvalidInputError(f"cannot read {what} from '{path}': {error.strerror or error}") from None
    if empty:
        raise InvalidInputError(f"cannot read {what} from '{path}': the file is empty")
    return path


@contextlib.contextmanager
def atomic_output(path, what: str = "a mesh"):
    """Yield a temporary path beside ``path`` (same folder, same extension) to write to; once the block completes,
    rename it onto ``path`` in one step (atomic on POSIX and Windows).  If the block fails or is interrupted
    (Ctrl-C, a full disk), the temporary file is removed and ``path`` keeps what it held before, or stays absent.

    Raises InvalidInputError when the folder does not exist or the rename fails.
    """
    with atomic_outputs([path], what) as (temporary,):
        yield temporary


@contextlib.contextmanager
def atomic_outputs(paths, what: str = "a mesh", stale=()):
    """:func:`atomic_output` for the files of one output written together (a mesh and its facets, an XDMF file and
    its HDF5 file): yield a list of temporary paths, one beside each of ``paths``; once the block completes, rename
    each onto its path and remove the ``stale`` files (an earlier output's companions that this one has not), with
    Ctrl-C and SIGTERM held off until all are done (:func:`signals_held`).  If the block fails or is interrupted,
    every temporary file is removed and every one of ``paths`` keeps what it held before, or stays absent.  A path
    that is a symbolic link is written through it (its target replaced); the half-written files that a killed
    write of the same path left (untouched for :data:`IDLE_SECONDS`: not those of another run writing it now) are
    removed first, with a note.

    Raises InvalidInputError when a folder does not exist or a rename fails.
    """
    paths = [Path(os.path.realpath(path)) if Path(path).is_symlink() else Path(path) for path in paths]
    for path in paths:
        if not path.parent.is_dir():
            raise InvalidInputError(f"cannot write {what} to '{path}': the directory '{path.parent}' does not exist")
        remove_stale_partials(path)
    temporaries = [_temporary_beside(path) for path in paths]
    replaced = []
    try:
        yield temporaries
        try:
            with signals_held():
                for temporary, path in zip(temporaries, paths):
                    os.replace(temporary, path)
                    replaced.append(path.name)
                for path in stale:
                    with contextlib.suppress(FileNotFoundError):
                        Path(path).unlink()
        except KeyboardInterrupt:   # held off until every file was in place: say so
            raise KeyboardInterrupt(f"{what} was written to '{paths[0]}' first") from None
    except OSError as error:
        kept = (f"only {', '.join(replaced)} replaced" if replaced else
                f"the previous file{'s' if len(paths) > 1 else ''}, if any, unchanged")
        raise InvalidInputError(f"cannot write {what} to '{paths[0]}': {error.strerror or error}; {kept}") from None
    finally:
        for temporary in temporaries:
            with contextlib.suppress(OSError):
                temporary.unlink()


@contextlib.contextmanager
def signals_held():
    """Ctrl-C (SIGINT) and SIGTERM held off while the block runs, then delivered: in the main thread, whose Python
    handlers they run (elsewhere the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending = []
    previous = {number: signal.signal(number, lambda number, _: pending.append(number))
                for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if pending:
            signal.raise_signal(pending[0])


#: the hex digits that make each temporary name of an atomic write fresh
TOKEN_BYTES = 4


def _partial_name(path: Path, token: str) -> str:
    """The hidden name beside ``path`` that an atomic write of it uses: ``.STEM.TOKEN.partial`` and the same
    extension (``.nii.gz`` kept whole)."""
    suffix = "".join(path.suffixes[-2:]) if path.name.lower().endswith(".nii.gz") else path.suffix
    return f".{path.stem}.{token}.partial{suffix}"


def _temporary_beside(path: Path) -> Path:
    """A fresh hidden name beside ``path`` for an atomic write of it."""
    return path.with_name(_partial_name(path, secrets.token_hex(TOKEN_BYTES)))


#: a half-written file of an atomic write untouched for this long (s) is a killed run's, not a live writer's (another
#: run writing the same output at the same time).
IDLE_SECONDS = 60.0


def stale_partials(path, idle: float = IDLE_SECONDS) -> list:
    """The half-written files that atomic writes of ``path`` left beside it when their process was killed before
    it could remove them (SIGKILL, out of memory), untouched for ``idle`` seconds at least; no other file's."""
    path = Path(path)
    if not path.parent.is_dir():
        return []
    prefix, suffix = _partial_name(path, "*").split("*")
    return sorted(other for other in path.parent.iterdir()
                  if other.name.startswith(prefix) and other.name.endswith(suffix)
                  and _is_token(other.name[len(prefix):len(other.name) - len(suffix)]) and _idle(other) >= idle)


def _idle(path: Path) -> float:
    """Seconds since ``path`` was last written; 0 when it is gone."""
    try:
        return time.time() - path.stat().st_mtime
    except OSError:
        return 0.0


def remove_stale_partials(path, idle: float = IDLE_SECONDS) -> int:
    """Remove the :func:`stale_partials` of ``path`` (untouched for ``idle`` seconds), with a note; how many were
    removed."""
    removed = 0
    for stale in stale_partials(path, idle):
        with contextlib.suppress(OSError):
            stale.unlink()
            removed += 1
    if removed:
        logger.info("removed %d half-written file(s) of '%s' that a killed run left beside it", removed,
                    Path(path).name)
    return removed


def _is_token(text: str) -> bool:
    return len(text) == 2 * TOKEN_BYTES and all(character in "0123456789abcdef" for character in text)


@contextlib.contextmanager
def vtk_silenced():
    """Stop VTK from printing errors and warnings (readers print instead of raising); restore afterwards."""
    from vtkmodules.vtkCommonCore import vtkObject

    previous = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        yield
    finally:
        vtkObject.SetGlobalWarningDisplay(previous)


@contextlib.contextmanager
def meshio_warnings():
    """Turn what meshio prints on stderr (through rich) into Python warnings."""
    captured = _stdio.StringIO()
    with contextlib.redirect_stderr(captured):
        yield
    text = " ".join(captured.getvalue().split())
    if text:
        warnings.warn(f"meshio: {text}", stacklevel=3)


def unit_rows(vectors: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    lengths = np.linalg.norm(vectors, axis=1, keepdims=True)
    return np.divide(vectors, lengths, out=np.zeros_like(vectors), where=lengths > 0)


def native(array) -> np.ndarray:
    """``array`` in native byte order (meshio's legacy VTK reader returns big-endian arrays)."""
    array = np.asarray(array)
    return array.astype(array.dtype.newbyteorder("="), copy=False) if array.dtype.byteorder not in "=|" else array
