"""Run in each worker of the embedded cluster as it starts (Dask's ``distributed.worker.preload``).

A terminal's Ctrl-C sends SIGINT to every process of the command, the cluster's workers included.  The driver
handles it (it cancels the cases, writes the summary and closes the cluster); a worker that also took it would
stop with a KeyboardInterrupt traceback of its own.  So the workers ignore SIGINT; they stop when the driver closes
the cluster.
"""
from __future__ import annotations

import signal


def dask_setup(worker) -> None:
    """Ignore SIGINT in this worker process (Dask calls this in the worker's main thread at its start)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
