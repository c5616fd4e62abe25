"""The thread count (issue 35): the same mesh bit for bit whatever the count, from any interface that sets it, and
from two Python threads meshing at once; a count the machine cannot give is refused naming where it came from.

The parallel kernels split loops whose iterations write only their own outputs, so the count cannot change a bit;
these tests hold that for scattered points (an ellipsoid with different semi-axes, hypothesis over seeds) and for
the shipped biv-me heart (labelled contours, whose grids are read through those kernels millions of times)."""
from __future__ import annotations

import threading

import numpy as np
import pytest
from bitemesh import Options, mesh
from bitemesh.core.compiled import THREADS_VARIABLE, available_threads, threads, using_threads
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.shapes import sample_surface
from bitemesh.core.sources.points import run
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.builders import ellipsoid

SAMPLES = sample_surface(ellipsoid(), spacing=0.06, seed=3)
MOST = available_threads()

needs_two_cores = pytest.mark.skipif(MOST < 2, reason="one core: nothing to compare")


def assert_same_mesh(first, second):
    assert np.array_equal(first.points, second.points) and np.array_equal(first.cells, second.cells)


@needs_two_cores
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1))
def test_one_thread_and_every_core_give_the_same_points_mesh(seed):
    biting = BitingParameters(cells=1500, seed=seed)
    with using_threads(1):
        single = run(*SAMPLES, biting=biting).mesh
    with using_threads(MOST):
        every = run(*SAMPLES, biting=biting).mesh
    assert_same_mesh(single, every)


@needs_two_cores
def test_one_thread_and_every_core_give_the_same_heart(gpfile):
    single = mesh(gpfile, cells=20000, threads=1).mesh
    every = mesh(gpfile, cells=20000, threads=MOST).mesh
    assert_same_mesh(single, every)
    assert {name: np.array_equal(single.cell_data[name], every.cell_data[name]) for name in single.cell_data} == \
        {name: True for name in single.cell_data}


def test_two_python_threads_meshing_at_once_give_the_mesh_of_one():
    """numba's workqueue layer stops the process when two threads launch a parallel kernel at once: the launches
    are taken in turn."""
    expected = run(*SAMPLES, biting=BitingParameters(cells=1500)).mesh
    results, errors = [None, None], []

    def work(slot):
        try:
            results[slot] = run(*SAMPLES, biting=BitingParameters(cells=1500)).mesh
        except Exception as error:   # noqa: BLE001 (reported below)
            errors.append(error)

    workers = [threading.Thread(target=work, args=(slot,)) for slot in range(2)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert not errors
    for result in results:
        assert_same_mesh(result, expected)


def test_the_count_follows_the_option_then_the_environment_then_the_cores(monkeypatch):
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    assert threads() == MOST
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    assert threads() == 1
    with using_threads(MOST):
        assert threads() == MOST
        with using_threads(None):   # an unset option keeps the count around it
            assert threads() == MOST
    assert threads() == 1


@pytest.mark.parametrize("value", [0, -1, 1.5, "two", MOST + 1])
def test_a_count_the_machine_cannot_give_is_refused_naming_the_option(value):
    with pytest.raises(InvalidInputError, match=r"threads \(--threads\) must be a whole number in \[1, \d+\].*"
                                                r"leave it unset to use every core"):
        Options(threads=value)


def test_a_bad_environment_variable_is_refused_by_name_before_any_work(monkeypatch):
    monkeypatch.setenv(THREADS_VARIABLE, "many")
    with pytest.raises(InvalidInputError, match=f"{THREADS_VARIABLE} must be a whole number.*got 'many'"):
        mesh(SAMPLES[0], cells=1000)



def test_rbf_patches_solve_on_one_blas_thread_and_evaluate_without_blas(monkeypatch):
    """OpenBLAS splits its sums by its thread count (every core by default): the RBF patches, solved and evaluated
    on bitemesh's threads, made the heart's mesh depend on the machine's cores (cine frame 8, 2 BLAS threads
    against 1: another mesh).  The solves take one BLAS thread, its count outside given back; the evaluation is
    bitemesh's own kernel: the same values, bit for bit, whatever threads BLAS or the kernels are given."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from bitemesh.core.compiled import using_threads
    from bitemesh.core.implicit import rbf

    def blas_threads():
        return {info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"}

    seen, solve = [], rbf._solve
    monkeypatch.setattr(rbf, "_solve", lambda *args: (seen.append(blas_threads()), solve(*args))[1])
    points = SAMPLES[0][:1500]
    with threadpool_limits(limits=2, user_api="blas"):
        outside = blas_threads()
        function = rbf.fit_rbf(points, SAMPLES[1][:1500])
        assert blas_threads() == outside
        with using_threads(2):
            values, slopes = function(points), function.gradient(points)
    assert len(function.patches) > 1 and seen and all(counts == {1} for counts in seen)
    with threadpool_limits(limits=1, user_api="blas"), using_threads(1):
        assert (function(points) == values).all() and (function.gradient(points) == slopes).all()


def test_threaded_map_keeps_the_order_and_drops_what_a_cancel_leaves():
    """threaded_map yields in the items' order on any thread count; when its caller stops (a cancel raised by a
    progress callback), the items not yet started are not run."""
    import time

    from bitemesh.core.compiled import threaded_map

    def slow(item):
        started.append(item)
        time.sleep(0.02 * (item % 3))
        return item * item

    for count in (1, MOST):
        started = []
        with using_threads(count):
            assert list(threaded_map(slow, range(12))) == [item * item for item in range(12)]
            started = []
            results = threaded_map(slow, range(40))
            assert next(results) == 0
            results.close()   # as when the caller's loop raises
        assert len(started) < 10


def test_blas_stays_on_one_thread_until_the_last_python_thread_leaves():
    """Two Python threads meshing at once: the first to leave must not give BLAS its threads back while the other
    still solves its patches (the limit is the process's)."""
    from threadpoolctl import threadpool_info

    from bitemesh.core.compiled import one_blas_thread

    def blas_threads():
        return {info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"}

    outside = blas_threads()
    if outside == {1}:
        pytest.skip("BLAS runs on one thread here: nothing to give back")
    entered, leave, seen = threading.Event(), threading.Event(), []

    def first():
        with one_blas_thread():
            entered.set()
            leave.wait(10)

    worker = threading.Thread(target=first)
    worker.start()
    entered.wait(10)
    with one_blas_thread():
        leave.set()
        worker.join(10)
        seen.append(blas_threads())   # the first thread has left
    assert seen == [{1}] and blas_threads() == outside
