"""``bitemesh.batch`` on the folder's 2-worker LocalCluster: six cases of every kind give the meshes of single
``bitemesh mesh`` runs bit for bit and one failed row; the summary and the offline report; a rerun skips what is
done; an interrupted run resumed meshes only the rest; a worker killed mid-run leaves every case done once."""
from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from bitemesh import batch
from bitemesh.cohorts.cases import RECORDS
from bitemesh.io import read_mesh

from tests.builders import leftovers
from tests.cohorts.conftest import FLAGS, OPTIONS, write_manifest

#: case -> (input, its own options): the manifest's rows
CASES = {"sphere": ("sphere", {}), "sphere_seed3": ("sphere", {"seed": 3}), "annulus": ("annulus", {"method": "rbf"}),
         "ball": ("ball", {}), "ball_ras": ("ball", {"ras": 1}), "broken": ("broken", {})}
#: the biv-me GPFile with its fibres (20 s a run: slow)
HEART = {"heart": ("heart", {"fibres": 1})}
COLUMNS = ("seed", "method", "ras", "fibres")
#: one BLAS thread, as Dask gives each worker: the RBF solves' last bits depend on the BLAS thread count
ONE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def flags_of(own: dict) -> list:
    """The ``bitemesh mesh`` flags of a case's own manifest columns."""
    return [flag for option, value in own.items() for flag in
            ([f"--{option.replace('_', '-')}"] if option in ("allow_implausible", "ras", "fibres") else
             [f"--{option}", str(value)])]


def mesh_both(client, cases: dict, inputs, folder):
    """``cases`` meshed by ``bitemesh.batch`` from a manifest and, at the same time, each valid one by a single
    ``bitemesh mesh`` run with one BLAS thread: (rows, output folder, folder of the single runs, manifest)."""
    output, single = folder / "cohort", folder / "single"
    single.mkdir()
    lines = [(inputs[source], name, *(own.get(column, "") for column in COLUMNS)) for name, (source, own) in
             cases.items()]
    manifest = write_manifest(folder / "cases.csv", lines, header=("input", "output", *COLUMNS))
    runs = [["mesh", str(inputs[source]), "-o", str(single / f"{name}.vtu"), *FLAGS, *flags_of(own)]
            for name, (source, own) in cases.items() if name != "broken"]
    references = subprocess.Popen(
        [sys.executable, "-c", f"from bitemesh import cli; assert all(cli.main(argv) == 0 for argv in {runs!r})"],
        env={**os.environ, **ONE_THREAD}, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        rows = batch([manifest], OPTIONS, client, output_dir=output)
    finally:
        _, errors = references.communicate(timeout=300)
    assert references.returncode == 0, errors
    return rows, output, single, manifest


def assert_same_meshes(rows, output, single) -> None:
    """Every done case's mesh equals its single run's, bit for bit, and has positive volumes."""
    for name in (row["case"] for row in rows if row["status"] == "done"):
        mine, theirs = read_mesh(output / f"{name}.vtu"), read_mesh(single / f"{name}.vtu")
        assert np.array_equal(mine.points, theirs.points) and np.array_equal(mine.cells, theirs.cells), name
        assert mine.cell_data.keys() == theirs.cell_data.keys()
        for key in mine.cell_data:
            assert np.array_equal(mine.cell_data[key], theirs.cell_data[key]), (name, key)
        assert (mine.cell_data["Volume"] > 0).all(), name


@pytest.fixture(scope="module")
def cohort(client, inputs, tmp_path_factory):
    return mesh_both(client, CASES, inputs, tmp_path_factory.mktemp("cases"))


def read_summary(folder):
    with open(folder / "summary.csv", newline="") as stream:
        return {row["case"]: row for row in csv.DictReader(stream)}


def test_each_case_is_the_mesh_of_its_single_run_bit_for_bit(cohort):
    rows, output, single, _ = cohort
    assert [row["case"] for row in rows if row["status"] == "done"] == [name for name in CASES if name != "broken"]
    assert_same_meshes(rows, output, single)
    ras, lps = read_mesh(output / "ball_ras.vtu"), read_mesh(output / "ball.vtu")
    assert np.array_equal(ras.points[:, :2], -lps.points[:, :2])   # the case's own ras column


@pytest.mark.slow
def test_a_gpfile_case_is_its_single_run_bit_for_bit(client, inputs, tmp_path):
    if "heart" not in inputs:
        pytest.skip("the biv-me GPFile of the real data folder is absent")
    rows, output, single, _ = mesh_both(client, {**HEART, "sphere": CASES["sphere"]}, inputs, tmp_path)
    assert [row["status"] for row in rows] == ["done", "done"]
    # a plausible heart; at this coarse size (1,500 cells) its RV wall is about one cell thick (half of the cells
    # on RV_ENDO reach EPI, the bound of --fibres' note), which --fibres may say, and nothing else
    notes = [note for note in rows[0]["message"].split("; ") if note]
    assert all(note.startswith("--fibres: the wall under") and "about one cell thick" in note
               for note in notes), notes
    assert_same_meshes(rows, output, single)   # the fibres of its fibres column too, as bitemesh mesh --fibres
    assert {"Fibre", "Sheet", "SheetNormal", "HelixAngle"} <= read_mesh(output / "heart.vtu").cell_data.keys()


def test_fibres_into_a_format_without_cell_arrays_fail_that_case_before_any_work(inputs, tmp_path):
    """No cluster starts: the case is refused while the cases are read, with the message of bitemesh mesh."""
    rows = batch([str(inputs["sphere"])], {**OPTIONS, "fibres": 1}, output_dir=tmp_path / "out", extension=".msh")
    assert [row["status"] for row in rows] == ["failed"]
    assert "--fibres: a .msh file keeps no cell arrays" in rows[0]["message"] and ".vtu" in rows[0]["message"]
    assert not (tmp_path / "out" / "sphere.msh").exists()


def test_a_broken_case_is_its_failed_row_and_the_others_go_on(cohort):
    rows, output, *_ = cohort
    summary = read_summary(output)
    assert list(summary) == [row["case"] for row in rows]
    broken = summary.pop("broken")
    assert broken["status"] == "failed" and "need at least 10 points" in broken["message"] and broken["cells"] == ""
    assert "\n" not in broken["message"] and not (output / "broken.vtu").exists()
    for name, row in summary.items():
        mesh = read_mesh(output / f"{name}.vtu")
        assert row["status"] == "done" and int(row["cells"]) == len(mesh.cells) > 500, row
        assert int(row["points"]) == len(mesh.points) and float(row["R"]) > 0
        assert 0 < float(row["min_Q"]) <= float(row["mean_Q"]) < 1
        assert float(row["volume"]) == pytest.approx(mesh.cell_data["Volume"].sum(), rel=1e-5)
        assert float(row["seconds"]) > 0 and float(row["fidelity"]) >= 0
    assert leftovers(output) == [] and leftovers(output / RECORDS) == []


def test_the_report_is_one_offline_page_failures_first(cohort):
    rows, output, *_ = cohort
    page = (output / "report.html").read_text()
    body = page.split("<tbody>")[1]
    assert body.index(">broken<") < min(body.index(f">{row['case']}<") for row in rows if row["case"] != "broken")
    assert page.count("src='data:image/png;base64,") == sum(row["status"] == "done" for row in rows)
    assert not re.search(r"(src|href)=['\"]?(https?:|//)", page) and "function sortBy" in page
    assert page.count("<tr>") == len(rows) + 1   # the headings' row and one per case


def test_a_rerun_skips_every_finished_case(cohort, client):
    rows, output, _, manifest = cohort
    before = {row["case"]: (output / row["output"]).stat().st_mtime_ns for row in rows if row["status"] == "done"}
    again = batch([manifest], OPTIONS, client, output_dir=output)
    assert {row["case"]: row["status"] for row in again} == \
        {row["case"]: "failed" if row["status"] == "failed" else "skipped" for row in rows}
    assert {name: (output / f"{name}.vtu").stat().st_mtime_ns for name in before} == before
    assert [row["cells"] for row in again] == [row["cells"] for row in rows]


def seeds_manifest(inputs, path, seeds, cells=1500):
    return write_manifest(path, [(inputs["sphere"], f"seed{seed}", seed, cells) for seed in seeds],
                          header=("input", "output", "seed", "cells"))


def running_tasks(dask_worker) -> int:
    """The tasks occupying a thread of this worker, cancelled ones included (the scheduler forgets a cancelled
    task at once, while its thread still finishes the case)."""
    return len(dask_worker.state.all_running_tasks)


def idle(client, timeout=60):
    """Wait until no task runs on the cluster (a cancelled task finishes its case first) and both workers are up."""
    client.wait_for_workers(2, timeout=timeout)
    deadline = time.monotonic() + timeout
    while any(client.run(running_tasks).values()) and time.monotonic() < deadline:
        time.sleep(0.1)


def test_an_interrupted_run_resumed_meshes_only_the_rest(client, inputs, tmp_path):
    manifest = seeds_manifest(inputs, tmp_path / "seeds.csv", range(5))
    output = tmp_path / "out"

    def interrupt(fraction, message=""):
        if fraction > 0:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        batch([manifest], OPTIONS, client, output_dir=output, progress=interrupt)
    first = read_summary(output)
    # the case that stopped the run, and any other whose record its worker wrote before the summary (the two
    # workers run two cases at a time): done; the rest cancelled
    done = [name for name, row in first.items() if row["status"] == "done"]
    assert len(first) == 5 and 1 <= len(done) <= 2, first
    assert {row["status"] for row in first.values()} == {"done", "cancelled"}
    assert all((output / RECORDS / f"{name}.json").exists() for name in done)
    idle(client)
    meshed = {name: (output / f"{name}.vtu").stat().st_mtime_ns for name in first
              if (output / RECORDS / f"{name}.json").exists()}
    assert len(meshed) < 5
    rows = batch([manifest], OPTIONS, client, output_dir=output)
    assert {row["case"]: row["status"] for row in rows} == \
        {name: "skipped" if name in meshed else "done" for name in first}
    assert {name: (output / f"{name}.vtu").stat().st_mtime_ns for name in meshed} == meshed


def test_a_worker_killed_mid_run_leaves_every_case_done_once(client, inputs, tmp_path):
    idle(client)
    manifest = seeds_manifest(inputs, tmp_path / "seeds.csv", range(6), cells=3000)
    output, result = tmp_path / "out", {}
    pids = client.run(os.getpid)
    run = threading.Thread(target=lambda: result.update(rows=batch([manifest], OPTIONS, client, output_dir=output)))
    run.start()
    deadline = time.monotonic() + 60
    while not any(client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)   # the case has started on its worker
    busy = next(worker for worker, keys in client.processing().items() if keys)
    os.kill(pids[busy], signal.SIGKILL)
    run.join(timeout=120)
    assert not run.is_alive()
    rows = result["rows"]
    assert [row["case"] for row in rows] == [f"seed{seed}" for seed in range(6)]
    assert all(row["status"] == "done" for row in rows), rows
    for row in rows:
        assert (read_mesh(output / row["output"]).cell_data["Volume"] > 0).all()
    assert len(list((output / RECORDS).glob("*.json"))) == 6 and leftovers(output) == []
    client.wait_for_workers(2, timeout=60)
    assert pids[busy] not in client.run(os.getpid).values()   # that worker did die (and was restarted)


def test_a_case_starting_removes_what_its_killed_attempt_half_wrote(inputs, tmp_path):
    """A worker killed mid-write leaves the case's .partial files (mesh, facets, picture, record); the next attempt
    of the case removes them and leaves another case's."""
    from bitemesh.cohorts.cases import RECORDS, Case
    from bitemesh.cohorts.run import remove_partials
    (tmp_path / RECORDS).mkdir()
    stale = [tmp_path / ".p1.0a1b2c3d.partial.vtu", tmp_path / ".p1_facets.5e6f7a8b.partial.vtu",
             tmp_path / RECORDS / ".p1.99887766.partial.png",
             tmp_path / RECORDS / ".p1.deadbeef.partial.json"]
    kept = [tmp_path / ".p10.0a1b2c3d.partial.vtu", tmp_path / ".p10_facets.0a1b2c3d.partial.vtu",
            tmp_path / RECORDS / "p1.json"]
    for path in stale + kept:
        path.write_text("x")
    remove_partials(tmp_path, Case("p1", inputs["sphere"]))
    assert not any(path.exists() for path in stale) and all(path.exists() for path in kept)
