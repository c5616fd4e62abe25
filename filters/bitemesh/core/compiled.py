"""Compiled kernels: numba's ``njit`` with its on-disk cache (compiled once after install, loaded from the cache
after), safe where the cache cannot be written (a full disk, a file size limit, a read-only install without a user
cache folder): the kernel then runs compiled in memory and a later process compiles it again; never an error."""
from __future__ import annotations

from numba import njit


def kernel(function):
    """``numba.njit(cache=True)(function)``, whose failure to find or write its cache is ignored."""
    try:
        dispatcher = njit(cache=True)(function)
    except RuntimeError:   # numba found no folder to cache in
        return njit(function)
    cache = dispatcher._cache   # numba's FunctionCache of this dispatcher (since numba 0.2x)
    save = cache.save_overload

    def save_overload(signature, result):
        try:
            save(signature, result)
        except OSError:   # the compiled code is already in the dispatcher: only the file is lost
            pass

    cache.save_overload = save_overload
    return dispatcher
