"""Run in each worker of the embedded cluster as it starts (Dask's ``distributed.worker.preload``).

A terminal's Ctrl-C sends SIGINT to every process of the command, the cluster's workers included.  The driver
handles it (it cancels the cases, writes the summary and closes the cluster); a worker that also took it would
stop with a KeyboardInterrupt traceback of its own.  So the workers ignore SIGINT; they stop when the driver closes
the cluster.  A worker whose heartbeat finds the scheduler already closed (the driver closed the cluster first), or
whose sending of a finished case to the driver finds the connection closed (Ctrl-C landed while the driver gathered
it), logs that with a traceback: the driver owns the cluster, so that is its shutdown, and the record is dropped.
"""
from __future__ import annotations

import logging
import signal


class DriverGoneFilter(logging.Filter):
    """Drops the records of a worker whose driver closed the cluster under it: the heartbeat's "Failed to communicate
    with scheduler", and "failed during get data" (a result sent to a driver that stopped gathering)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(("Failed to communicate with scheduler during heartbeat",
                                                   "failed during get data with"))


def dask_setup(worker) -> None:
    """Ignore SIGINT in this worker process and drop the records of its driver's shutdown (Dask calls this in the
    worker's main thread at its start)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed.worker").addFilter(DriverGoneFilter())
