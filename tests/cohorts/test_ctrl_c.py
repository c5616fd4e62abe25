"""Ctrl-C on a real ``bitemesh batch`` process: SIGINT to its whole process group, as a terminal sends it (the
embedded cluster's scheduler, nannies and workers get it too).  The command stops with exit code 130 and the
summary of what finished, leaves no process and no half-written file behind, and the same command run again
meshes only the cases that were not finished."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from bitemesh.cohorts.cases import RECORDS
from bitemesh.io import read_mesh

from tests.builders import leftovers
from tests.cohorts.conftest import FLAGS
from tests.cohorts.test_batch import ONE_THREAD, read_summary, seeds_manifest

#: cases in the run: with one worker they finish one after the other, so Ctrl-C lands with some done, some not
CASES = 8


def batch_command(manifest, output) -> list:
    return [sys.executable, "-m", "bitemesh.cli", "batch", str(manifest), "-o", str(output), "--workers", "1", *FLAGS]


def group_is_gone(group: int, timeout: float) -> bool:
    """True once no process of the process group ``group`` is left (waiting up to ``timeout`` seconds)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.2)
    return False


def test_ctrl_c_stops_the_command_with_its_summary_and_the_rerun_meshes_the_rest(inputs, tmp_path):
    manifest = seeds_manifest(inputs, tmp_path / "seeds.csv", range(CASES))
    output = tmp_path / "out"
    environment = {**os.environ, **ONE_THREAD}
    command = batch_command(manifest, output)
    process = subprocess.Popen(command, env=environment, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not list((output / RECORDS).glob("*.json")) and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 130, (out, err)
    assert "bitemesh: interrupted; the summary of the finished cases is in" in err, err
    assert "Traceback" not in err, err
    assert group_is_gone(process.pid, timeout=30), "processes of the batch are left after Ctrl-C"

    first = read_summary(output)
    statuses = {name: row["status"] for name, row in first.items()}
    assert set(statuses) == {f"seed{seed}" for seed in range(CASES)}
    done = {name for name, status in statuses.items() if status == "done"}
    assert done and set(statuses.values()) == {"done", "cancelled"}, statuses
    for name in done:   # a finished case: its mesh is whole and its record written
        assert (read_mesh(output / first[name]["output"]).cell_data["Volume"] > 0).all()
        assert (output / RECORDS / f"{name}.json").is_file()
    assert leftovers(output) == []
    written = {name: (output / f"{name}.vtu").stat().st_mtime_ns for name in done}

    again = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    second = read_summary(output)
    assert {name: row["status"] for name, row in second.items()} == \
        {name: "skipped" if name in done else "done" for name in statuses}
    assert {name: (output / f"{name}.vtu").stat().st_mtime_ns for name in done} == written   # not meshed again
    assert f"{CASES} cases: {CASES - len(done)} done, {len(done)} skipped, 0 failed" in again.stdout


def test_a_worker_drops_only_the_records_of_its_drivers_shutdown():
    """Ctrl-C while the driver gathers a finished case: the worker logs 'failed during get data' with the closed
    connection's traceback (seen once in a full run on a busy machine); the heartbeat's record of a closed scheduler
    likewise. Both are the driver's shutdown; any other record of the worker passes."""
    import logging

    from bitemesh.cohorts.worker_start import DriverGoneFilter

    def record(message):
        return logging.LogRecord("distributed.worker", logging.ERROR, __file__, 1, message, None, None)

    gone = DriverGoneFilter()
    assert not gone.filter(record("failed during get data with tcp://127.0.0.1:33431 -> None"))
    assert not gone.filter(record("Failed to communicate with scheduler during heartbeat."))
    assert gone.filter(record("Compute Failed"))
