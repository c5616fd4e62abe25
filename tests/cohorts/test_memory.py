"""A case over the worker memory limit fails alone: its worker is restarted, the case run again once
(``retries=1``), then failed as its row; the other case is done.  On bitemesh.batch's own embedded LocalCluster."""
from __future__ import annotations

import csv

import pytest
from bitemesh import batch
from bitemesh.io import read_mesh

from tests.cohorts.conftest import OPTIONS, ball_file

pytest.importorskip("distributed")


def test_a_case_over_the_worker_memory_limit_fails_alone(inputs, tmp_path):
    # 240^3 voxels: its signed distance and grid need about 800 MB, a sphere of 1,500 cells about 250 MB
    big = ball_file(tmp_path / "big.nrrd", size=240, spacing=0.1)
    rows = batch([inputs["sphere"], big], OPTIONS, output_dir=tmp_path / "out", workers=2, worker_memory="400MB",
                 retries=1)
    sphere, too_big = rows
    assert sphere["status"] == "done" and (read_mesh(tmp_path / "out" / "sphere.vtu").cell_data["Volume"] > 0).all()
    assert too_big["status"] == "failed" and "--worker-memory" in too_big["message"], too_big
    assert not (tmp_path / "out" / "big.vtu").exists()
    with open(tmp_path / "out" / "summary.csv", newline="") as stream:
        summary = list(csv.DictReader(stream))
    assert [(row["case"], row["status"]) for row in summary] == [("sphere", "done"), ("big", "failed")]
    assert summary[1]["message"] == too_big["message"]
