"""A compiled kernel whose cache numba cannot write (a full disk, a file size limit, as on the first run of an
install) runs compiled in memory: no error, the right value (bitemesh.core.compiled.kernel).  numba's own
``njit(cache=True)`` stops there with ``OSError: [Errno 27] File too large``."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import bitemesh

SCRIPT = """
import resource, signal
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # a write past the limit fails with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (16, 16))
import numpy as np
from bitemesh.core.compiled import kernel

@kernel
def total(values):
    sum = 0.0
    for value in values:
        sum += value
    return sum

print(total(np.arange(10.0)))
"""


@pytest.mark.skipif(os.name != "posix", reason="RLIMIT_FSIZE is POSIX")
def test_a_kernel_whose_cache_cannot_be_written_runs(tmp_path):
    script = tmp_path / "summing.py"
    script.write_text(SCRIPT)
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
                   "PYTHONPATH": str(Path(bitemesh.__file__).parents[1])}
    result = subprocess.run([sys.executable, str(script)], env=environment, capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    assert result.stdout.strip() == "45.0"
