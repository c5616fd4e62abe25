"""Run in each worker of the embedded cluster as it starts (Dask's ``distributed.worker.preload``).

A terminal's Ctrl-C sends SIGINT to every process of the command, the cluster's workers included.  The driver
handles it (it cancels the cases, writes the summary and closes the cluster); a worker that also took it would
stop with a KeyboardInterrupt traceback of its own.  So the workers ignore SIGINT; they stop when the driver closes
the cluster.  A worker whose heartbeat finds the scheduler already closed (the driver closed the cluster first)
logs that with a traceback: the driver owns the cluster, so that is its shutdown, and the record is dropped.
"""
from __future__ import annotations

import logging
import signal


class ClosedSchedulerFilter(logging.Filter):
    """Drops the heartbeat's "Failed to communicate with scheduler" record of a worker whose scheduler is gone."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Failed to communicate with scheduler during heartbeat")


def dask_setup(worker) -> None:
    """Ignore SIGINT in this worker process and drop the closed scheduler's heartbeat record (Dask calls this in
    the worker's main thread at its start)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed.worker").addFilter(ClosedSchedulerFilter())
