"""Mesh a cohort on dask.distributed: one task per case, each isolated (its failure is its summary row), resumable
(a case whose output and record match its hash is skipped), interruptible (Ctrl-C writes the summary of what
finished).

dask and distributed are imported only inside :func:`batch` and :func:`cluster_client`: the rest of bitemesh never
needs them.
"""
from __future__ import annotations

import contextlib
import logging
import os
import secrets
import time
import warnings
from pathlib import Path

from ..core.compiled import using_threads
from ..core.errors import BitemeshError, InvalidInputError
from ..core.fem.template import FitParameters
from ..core.mesh.quality import quality_summary
from ..core.progress import ProgressCallback
from ..fitting import fit, template_mesh
from ..io import mesh_files, remove_stale_partials
from ..meshing import check_output, mesh, write
from ..options import RUNNING, Options, as_options
from .cases import Case, case_hash, find_cases, record_path, recorded_row, write_record
from .report import picture_path, render_cut, save_picture, write_report, write_summary
from .shapes import write_shape_model

#: the columns of summary.csv (R, fidelity and volume in input units; seconds of wall clock on the worker)
COLUMNS = ("case", "status", "message", "cells", "points", "R", "mean_Q", "min_Q", "min_dihedral", "fidelity",
           "volume", "seconds", "input", "output")
#: how many times a case is run again after its worker died (Dask's distributed.scheduler.allowed-failures)
RETRIES = 2
#: glibc's trim and mmap thresholds in the embedded cluster's workers, bytes.  Dask sets MALLOC_TRIM_THRESHOLD_
#: (64 KiB) in its workers, and any fixed trim threshold turns off glibc's dynamic mmap threshold: every numpy
#: temporary over 128 KiB is then mapped and unmapped, page faults each time.  Measured on one 6,000-cell sphere
#: (CPU): 1.48 s unset, 2.48 s at 64 KiB, 2.10 s at 64 MiB, 1.34 s at 64 MiB with the mmap threshold at 64 MiB too;
#: 64 MiB still gives the memory of a finished case back.
TRIM = 2**26


def one_line(text) -> str:
    return " ".join(str(text).split())


def row_of(case: Case, status: str, message: str = "", **values) -> dict:
    """A summary row: every column, empty where there is no value."""
    row = dict.fromkeys(COLUMNS, "")
    row.update(case=case.name, status=status, message=one_line(message), input=str(case.input),
               output=case.output_name, **values)
    return row


class _Captured(logging.Handler):
    """The bitemesh logger's warnings during one case."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def remove_partials(output_dir: Path, case: Case) -> None:
    """Delete what attempts of ``case`` half wrote (its mesh with its companion files, picture and record) when
    their worker was killed mid-write: one attempt of a case runs at a time, so those found when it starts are
    stale, however recent."""
    for path in (*mesh_files(output_dir / case.output_name), picture_path(output_dir, case.name),
                 record_path(output_dir, case)):
        remove_stale_partials(path, idle=0.0)


def made(case: Case, options: dict, fitting: dict | None):
    """The case's mesh (a MeshingResult, or a TemplateFit when ``fitting`` names a template) and its summary
    values: R and the fidelity (the data's mean distance to the boundary, input units)."""
    if fitting is None:
        result = mesh(case.input, {**options, **case.options})
        return result, {"R": result.radius,
                        "fidelity": "" if result.fidelity is None else result.fidelity.to_boundary_mean}
    fitted = fit(fitting["template"], case.input, frame=case.options.get("frame"), pull=fitting["pull"])
    return fitted, {"fidelity": float(fitted.distances.mean())}


def run_case(case: Case, options: dict, output_dir: str, digest: str, fitting: dict | None = None) -> dict:
    """The task of one case, run on a worker: mesh ``case.input`` as ``bitemesh mesh`` would with ``options`` under
    the case's own (or fit the template of ``fitting``, ``{"template": path, "pull": float}``, as ``bitemesh fit``
    would), write the mesh (atomically), its picture and its record; return its summary row.  Every error of the
    case is its row ("failed", the one-line message); a case already recorded with ``digest`` (its task run again
    after a worker died) is returned as recorded, not meshed twice."""
    output_dir = Path(output_dir)
    row = recorded_row(output_dir, case, digest)
    if row is not None:
        return row
    remove_partials(output_dir, case)   # of an attempt whose worker died while writing
    start = time.perf_counter()
    logger, captured = logging.getLogger("bitemesh"), _Captured()
    logger.addHandler(captured)
    try:
        threads = {**options, **case.options}.get("threads") or 1   # one a worker unless given
        with warnings.catch_warnings(record=True) as caught, using_threads(threads):
            warnings.simplefilter("always")
            result, values = made(case, options, fitting)
            write(result, output_dir / case.output_name)
    except Exception as error:   # noqa: BLE001 (one case's failure, whatever it is, is its row)
        message = str(error) if isinstance(error, BitemeshError) else f"{type(error).__name__}: {error}"
        return row_of(case, "failed", message, seconds=round(time.perf_counter() - start, 3))
    finally:
        logger.removeHandler(captured)
    summary = quality_summary(result.mesh)
    notes = captured.messages + [str(warning.message) for warning in caught]
    row = row_of(case, "done", "; ".join(dict.fromkeys(notes)), cells=summary.n_cells, points=summary.n_points,
                 mean_Q=summary.q_mean, min_Q=summary.q_min, min_dihedral=summary.angle_min,
                 volume=summary.total_volume, seconds=round(time.perf_counter() - start, 3), **values)
    save_picture(output_dir, case.name, render_cut(result.mesh))
    write_record(output_dir, case, digest, row)
    return row


@contextlib.contextmanager
def cluster_client(client=None, scheduler=None, workers=None, worker_memory=None, retries=RETRIES):
    """Yield a dask.distributed Client: ``client`` itself (left open), one connected to ``scheduler`` (or to
    $DASK_SCHEDULER_ADDRESS), else an embedded LocalCluster of ``workers`` processes (default: one per core), one
    thread each, each restarted when it passes ``worker_memory`` (bytes or "2GB"), a case failed once its
    workers died ``retries`` + 1 times.  Closed (the cluster too) on exit, Ctrl-C included."""
    if client is not None:
        yield client
        return
    import dask
    from distributed import Client, LocalCluster

    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if scheduler:
        with Client(scheduler) as connected:
            yield connected
        return
    settings = {"distributed.scheduler.allowed-failures": retries,
                # a worker is restarted over its memory limit, never paused nor spilling (tasks hold no data)
                "distributed.worker.memory.pause": False, "distributed.worker.memory.spill": False,
                "distributed.worker.memory.target": False,
                # the worker's sampling profiler, GIL monitor and 20 ms event-loop tick take the GIL from the
                # case's thread: a case ran up to 1.7x slower than in a plain process (benchmarks/batch.md)
                "distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s",
                "distributed.admin.system-monitor.gil.enabled": False,
                "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": TRIM,
                "distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": TRIM,
                # a terminal's Ctrl-C reaches every process of the command: the workers leave it to the driver
                "distributed.worker.preload": ["bitemesh.cohorts.worker_start"]}
    with dask.config.set(settings), \
            LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                         memory_limit=worker_memory or "auto",
                         dashboard_address=":0") as cluster, Client(cluster) as local:
        yield local


class CancelRaceFilter(logging.Filter):
    """Drops the one traceback distributed (2026.8) logs when Ctrl-C lands in a blocking call whose coroutine has
    not started yet: its cancel callback reads an unbound ``future`` (NameError in distributed/utils.py).  Nothing
    is lost: the run stops and the cluster closes right after.  Every other record passes."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if not isinstance(error, NameError) or error.__traceback__ is None:
            return True
        last = error.__traceback__
        while last.tb_next is not None:
            last = last.tb_next
        code = last.tb_frame.f_code
        return not (code.co_name == "cancel" and Path(code.co_filename).parts[-2:] == ("distributed", "utils.py"))


@contextlib.contextmanager
def quiet_cancel_race():
    """:class:`CancelRaceFilter` on tornado's callback logger for the duration of the block."""
    logger, race = logging.getLogger("tornado.application"), CancelRaceFilter()
    logger.addFilter(race)
    try:
        yield
    finally:
        logger.removeFilter(race)


def dashboard_link(client):
    """The Dask dashboard's address, or None when the scheduler serves none (bokeh absent)."""
    with contextlib.suppress(Exception):
        if "dashboard" in client.scheduler_info().get("services", {}):
            return client.dashboard_link
    return None


def collected(future, case: Case) -> dict:
    """The row a finished task returned; a worker that died too often (KilledWorker) or any failure of Dask itself
    is the case's failed row."""
    from distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker:
        return row_of(case, "failed", "its worker died each time it meshed this case (killed, or over the worker "
                      "memory limit --worker-memory); give the workers more memory or a coarser mesh")
    except Exception as error:   # noqa: BLE001
        return row_of(case, "failed", f"{type(error).__name__}: {error}")


def batch(cases, options=None, client=None, *, output_dir, template=None, pull: float = 3.0, workers=None,
          worker_memory=None, retries=RETRIES, scheduler=None, extension=".vtu", progress: ProgressCallback = None,
          on_client=None) -> list:
    """Mesh every case as ``bitemesh mesh`` would (or, with ``template``, fit it to each case as ``bitemesh fit``
    would), one Dask task each, into ``output_dir``; write its summary.csv and report.html; return the summary rows
    (dicts of :data:`COLUMNS`), in the order of the cases.

    Parameters
    ----------
    cases : files, folders, glob patterns, manifest CSVs or :class:`Case` objects
    options : mapping of ``bitemesh mesh`` option names to values (``cells=1500``), under each case's own
    template : a bitemesh mesh file with its tags: every case is this template fitted to its data (the same cells),
        the report adds the cohort's mean shape and modes (``output_dir/shape/``); no mesh option applies then but
        ``frame`` (a manifest column)
    pull : the fit's pull (:class:`~bitemesh.core.fem.template.FitParameters`)
    client : a dask.distributed Client to use (left open); default: ``scheduler`` or an embedded LocalCluster of
        ``workers`` processes, ``worker_memory`` each, closed at the end
    retries : how many times a case runs again after its worker died (embedded cluster only)
    extension : the mesh format of cases whose name has none (.vtu, .vtk, .msh, .inp, .mesh)
    progress : callable(fraction, message), called as cases finish
    on_client : callable(client), called once the client is up (the CLI prints the dashboard's address)

    A case whose output exists and whose record holds the hash of its input and options is skipped (status
    "skipped", its recorded values).  Ctrl-C (KeyboardInterrupt) cancels the rest, closes the cluster, writes the
    summary (status "cancelled" for the cases not finished; "done" for one that finished as the run stopped) and is
    raised again.
    """
    from distributed import as_completed

    check_cluster(client, scheduler, workers, worker_memory, retries)
    cases = find_cases(cases, extension)
    options = dict(options or {})
    as_options(options)
    fitting = fitted_cohort(template, pull, options)
    if not cases:
        raise InvalidInputError("no cases: the inputs hold no file bitemesh can mesh")
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    digests, rows = {}, {}
    for case in cases:
        try:
            check_output(output_dir / case.output_name, {**options, **case.options})   # refused before any work
            digests[case.name] = case_hash(case, options, fitting)
            if fitting is not None:
                check_fitted_case(case)
        except OSError as error:
            rows[case.name] = row_of(case, "failed", f"cannot read '{case.input}': {error.strerror or error}")
            continue
        except BitemeshError as error:
            rows[case.name] = row_of(case, "failed", error)
            continue
        recorded = recorded_row(output_dir, case, digests[case.name])
        if recorded is not None:
            notes = f": {recorded['message']}" if recorded["message"] else ""
            rows[case.name] = {**recorded, "status": "skipped",
                               "message": f"up to date (input and options unchanged){notes}"}
    todo = [case for case in cases if case.name not in rows]
    if not todo:   # nothing left to mesh: no cluster started
        return finished(rows, cases, output_dir, fitting)
    report = progress or (lambda fraction, message="": None)
    try:
        with quiet_cancel_race(), cluster_client(client, scheduler, workers, worker_memory, retries) as connected:
            if on_client is not None:
                on_client(connected)
            futures = {connected.submit(run_case, case, options, str(output_dir), digests[case.name], fitting,
                                        key=f"bitemesh-{case.name}-{secrets.token_hex(4)}", pure=False):
                       case for case in todo}
            report(len(rows) / len(cases), f"{len(rows)}/{len(cases)} cases")
            try:
                for future in as_completed(futures):
                    case = futures[future]
                    rows[case.name] = collected(future, case)
                    failed = sum(row["status"] == "failed" for row in rows.values())
                    report(len(rows) / len(cases), f"{len(rows)}/{len(cases)} cases, {failed} failed")
            except KeyboardInterrupt:
                connected.cancel(list(futures))
                raise
    except KeyboardInterrupt:   # (an embedded cluster is closed by now) a case whose record is written did finish
        for case in cases:
            if case.name not in rows:
                rows[case.name] = recorded_row(output_dir, case, digests[case.name]) or row_of(
                    case, "cancelled", "not finished: the run was interrupted; run the same command again to mesh it")
        finished(rows, cases, output_dir, fitting)
        raise
    return finished(rows, cases, output_dir, fitting)


def check_cluster(client, scheduler, workers, worker_memory, retries) -> None:
    """Refuse cluster settings that cannot apply, naming the setting, the value and the hint."""
    from dask.utils import parse_bytes

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InvalidInputError(f"workers must be a whole number >= 1, got {workers!r}")
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InvalidInputError(f"retries must be a whole number >= 0, got {retries!r}")
    if worker_memory is not None:
        try:
            size = parse_bytes(worker_memory)
        except (TypeError, ValueError):
            size = None
        if size is None or size < 2**26:
            raise InvalidInputError(f"worker_memory (--worker-memory) must be a size of at least 64MB such as "
                                    f"'2GB' or a number of bytes, got {worker_memory!r}")
    given = [name for name, value in (("workers", workers), ("worker_memory", worker_memory)) if value is not None]
    if given and (client is not None or scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")):
        raise InvalidInputError(f"{given[0]} applies to the embedded cluster, not to a given client or scheduler "
                                "(whose workers are set where the cluster is started); leave it out")


def fitted_cohort(template, pull: float, options: dict):
    """``{"template": path, "pull": pull}`` for a cohort fitted with ``template`` (read now: a bad template is
    refused before any case), None without one; refuses mesh options, which a fit does not use."""
    if template is None:
        return None
    FitParameters(pull)
    template_mesh(template)
    defaults = Options().as_dict()
    running = {name for name, *_ in RUNNING}
    changed = [name for name, value in as_options(options).as_dict().items()
               if value != defaults[name] and name not in running]
    if changed:
        raise InvalidInputError(f"{changed[0]} (--{changed[0].replace('_', '-')}) is an option of meshing; with a "
                                "template each case is the template fitted to its data, so no mesh option "
                                "applies: leave it out, or mesh the template itself with it")
    return {"template": str(template), "pull": float(pull)}


def check_fitted_case(case: Case) -> None:
    """A case of a fitted cohort may pick only its frame (a manifest's ``frame`` column)."""
    other = [name for name in case.options if name != "frame"]
    if other:
        raise InvalidInputError(f"manifest column {other[0]!r} is an option of meshing; with a template a case "
                                "may only pick its frame: leave the column out")


def finished(rows: dict, cases, output_dir: Path, fitting: dict | None = None) -> list:
    """The rows in the cases' order, written to summary.csv and report.html (with the shape model of a fitted
    cohort)."""
    ordered = [rows[case.name] for case in cases]
    modes = None if fitting is None else write_shape_model(ordered, output_dir, template_mesh(fitting["template"]))
    write_summary(ordered, output_dir, COLUMNS)
    write_report(ordered, output_dir, modes)
    return ordered
