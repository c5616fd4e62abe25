"""The fixtures shared by the test folders: where the real data lives, the biv-me patient's GPFile in it, the elastic
template of its cine cycle, and a small sphere's samples.  (The builders they use: tests/builders.py.)"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from bitemesh.core.compiled import THREADS_VARIABLE
from tests import builders

DATA = Path(os.environ.get("BITEMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def pytest_configure(config):
    """Each pytest-xdist worker (one per core) takes one thread for bitemesh's kernels, as Dask workers do: two
    workers of two threads each on 2 cores took 15 % longer (the heart files: 251 s against 213 s), the threads
    waiting on each other.  The tests of the thread count set theirs (tests/core/test_threads.py); the programs the
    tests start inherit it, and one BLAS thread (the workers' own BLAS keeps its count: the RBF patches hold it to
    one, and tests/core/test_threads.py checks that the count is given back)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        for name in (THREADS_VARIABLE, "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(name, "1")


def pytest_collection_modifyitems(items):
    """The files that hold slow cases run first: pytest-xdist hands out whole files in this order
    (--dist=loadfile), so that the quick files fill both workers' ends, not a slow one running alone."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture
def shared_data() -> Path:
    """The folder of real data (../shared/data beside the clone); skip where it is absent."""
    if not DATA.is_dir():
        pytest.skip(f"real data folder {DATA} is absent (set BITEMESH_DATA)")
    return DATA


@pytest.fixture
def gpfile(shared_data) -> Path:
    """biv-me's first patient, time frame 0: the GPFile of the real data folder (skip where it is absent)."""
    return shared_data / "bivme_patient1" / "GPFile_000.txt"


@pytest.fixture(scope="package")
def unit_sphere_samples():
    """(points, unit outward normals) on the unit sphere, about 0.1 apart (1,500 points): the awkward inputs'
    sphere, each test making its own variant of it.  Built once per test folder; the tests only read it."""
    return builders.sphere_samples(0.1)


@pytest.fixture(scope="session")
def cine(tmp_path_factory):
    """(the folder of biv-me patient1's cine cycle, the template: its frame 0 meshed by ``bitemesh mesh --cells
    20000``), meshed once per session; skip where the data is absent."""
    from tests.cli.commands import run_quietly
    folder = DATA / "bivme_patient1_cine"
    if not folder.is_dir():
        pytest.skip(f"{folder} is absent")
    template = tmp_path_factory.mktemp("cine_template") / "template.vtu"
    assert run_quietly(["mesh", str(folder / "guidepoints" / "GPFile_000.txt"), "--cells", "20000",
                        "-o", str(template)]) == 0
    return folder, template
