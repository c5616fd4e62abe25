"""Compiled kernels: numba's ``njit`` with its on-disk cache (compiled once after install, loaded from the cache
after), safe where the cache cannot be written (a full disk, a file size limit, a read-only install without a user
cache folder): the kernel then runs compiled in memory and a later process compiles it again; never an error.

A parallel kernel (``@kernel(parallel=True)``) splits a loop of independent iterations (``numba.prange``; each writes
only its own outputs, so that the result does not depend on the thread count, bit for bit) over :func:`threads`
threads: the count :func:`using_threads` set in this context, else the environment variable ``BITEMESH_THREADS``,
else every core numba sees (``NUMBA_NUM_THREADS``).  Launches are taken one at a time: numba's threading layer of
the PyPI wheels (workqueue) stops the whole process when two Python threads launch at once.

Where bitemesh runs BLAS on its own threads (the RBF patches' solves), BLAS takes one thread
(:func:`one_blas_thread`): OpenBLAS's sums, split by its own thread count (every core by default), gave a mesh that
depended on the machine's cores, and one thread a solve is faster (patches of 1,100 constraints: 34 ms each on 1
BLAS thread, 49 ms on 2, 20 ms two at a time).
"""
from __future__ import annotations

import contextvars
import functools
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numba
from numba import njit
from threadpoolctl import threadpool_limits

from .errors import InvalidInputError

#: the environment variable that sets the thread count where no option does
THREADS_VARIABLE = "BITEMESH_THREADS"
_chosen = contextvars.ContextVar("bitemesh_threads", default=None)
_launch = threading.Lock()


def kernel(function=None, *, parallel: bool = False):
    """``numba.njit(cache=True)(function)``, whose failure to find or write its cache is ignored; with ``parallel``,
    compiled with ``parallel=True`` and launched on :func:`threads` threads (see the module)."""
    if function is None:
        return functools.partial(kernel, parallel=parallel)
    try:
        dispatcher = njit(cache=True, parallel=parallel)(function)
    except RuntimeError:   # numba found no folder to cache in
        dispatcher = njit(parallel=parallel)(function)
    else:
        cache = dispatcher._cache   # numba's FunctionCache of this dispatcher (since numba 0.2x)
        save = cache.save_overload

        def save_overload(signature, result):
            try:
                save(signature, result)
            except OSError:   # the compiled code is already in the dispatcher: only the file is lost
                pass

        cache.save_overload = save_overload
    return _Parallel(dispatcher) if parallel else dispatcher


class _Parallel:
    """A parallel kernel called from Python: one launch at a time, on :func:`threads` threads."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        functools.update_wrapper(self, dispatcher.py_func)

    def __call__(self, *args):
        count = threads()
        with _launch:
            numba.set_num_threads(count)   # numba keeps it per Python thread
            return self.dispatcher(*args)


def available_threads() -> int:
    """The cores numba runs on (``NUMBA_NUM_THREADS``, every core by default): the most threads a kernel takes."""
    return numba.config.NUMBA_NUM_THREADS


def check_threads(value, name: str = "threads (--threads)") -> int:
    """``value`` as a thread count in [1, :func:`available_threads`], or an error naming ``name``."""
    most = available_threads()
    try:
        count = int(value)
        valid = count == float(value) and 1 <= count <= most
    except (TypeError, ValueError):
        valid = False
    if not valid:
        raise InvalidInputError(f"{name} must be a whole number in [1, {most}] (this machine's cores as numba sees "
                                f"them), got {value!r}: leave it unset to use every core")
    return count


def threads() -> int:
    """The thread count parallel kernels take here and now (see the module)."""
    chosen = _chosen.get()
    if chosen is not None:
        return chosen
    variable = os.environ.get(THREADS_VARIABLE, "").strip()
    return check_threads(variable, THREADS_VARIABLE) if variable else available_threads()


@contextmanager
def using_threads(count=None):
    """Parallel kernels take ``count`` threads inside the block (None: as outside it, :func:`threads`, checked
    now)."""
    token = _chosen.set(threads() if count is None else check_threads(count))
    try:
        yield
    finally:
        _chosen.reset(token)


class _OneBlasThread:
    """BLAS held to one thread while any Python thread is inside :func:`one_blas_thread` (the limit is the
    process's: the first to enter sets it, the last to leave gives the count back)."""

    def __init__(self):
        self.lock, self.inside, self.limit = threading.Lock(), 0, None

    @contextmanager
    def __call__(self):
        with self.lock:
            if not self.inside:
                self.limit = threadpool_limits(limits=1, user_api="blas")
            self.inside += 1
        try:
            yield
        finally:
            with self.lock:
                self.inside -= 1
                if not self.inside:
                    self.limit.restore_original_limits()


#: a context in which BLAS takes one thread, its count given back after, whatever other Python threads do (see the
#: module)
one_blas_thread = _OneBlasThread()


def threaded_map(function, items):
    """``function(item)`` for each of ``items`` on :func:`threads` Python threads (work that releases the GIL: numpy,
    LAPACK, compiled kernels), yielded in the items' order, so that a sum over them is the same whatever the count;
    the items not yet started are dropped when the caller stops early (an error, a cancel)."""
    count = threads()
    if count == 1:
        yield from map(function, items)
        return
    pool = ThreadPoolExecutor(count)
    try:
        yield from pool.map(function, items)
    finally:
        pool.shutdown(cancel_futures=True)
