"""``bitemesh batch``: the same flags as ``bitemesh mesh``, the cases sent to a running scheduler (--scheduler),
a failed case's line and exit code 1, bad cluster settings refused in one line."""
from __future__ import annotations

import csv

import pytest
from bitemesh import cli
from bitemesh.io import read_mesh

from tests.cli.commands import assert_one_line_error
from tests.cohorts.conftest import FLAGS


def test_batch_sends_the_cases_to_a_scheduler_and_reports(client, inputs, tmp_path, capsys):
    output = tmp_path / "out"
    code = cli.main(["batch", str(inputs["sphere"]), str(inputs["broken"]), "-o", str(output), "--format", ".msh",
                     "--scheduler", client.scheduler.address, *FLAGS, "--seed", "2"])
    out, err = capsys.readouterr()
    assert code == 1 and "bitemesh: error: 1 of 2 cases failed" in err, err
    assert "2 cases: 1 done, 0 skipped, 1 failed" in out and "  broken: points: need at least 10 points" in out
    assert "Dask: 2 workers" in out
    with open(output / "summary.csv", newline="") as stream:
        rows = {row["case"]: row for row in csv.DictReader(stream)}
    assert rows["sphere"]["output"] == "sphere.msh" and int(rows["sphere"]["cells"]) == \
        len(read_mesh(output / "sphere.msh").cells)
    assert (output / "report.html").is_file()


@pytest.mark.parametrize("flags, words", [
    (["--workers", "0"], ["workers", ">= 1", "0"]),
    (["--worker-memory", "lots"], ["worker_memory", "--worker-memory", "lots", "2GB"]),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], ["workers", "embedded cluster"]),
    (["--radius", "-2"], ["radius", "-2"]),
])
def test_bad_settings_are_refused_before_any_case(flags, words, inputs, tmp_path, capsys):
    code = cli.main(["batch", str(inputs["sphere"]), "-o", str(tmp_path / "out"), *flags])
    assert_one_line_error(capsys, code, *words)
    assert not (tmp_path / "out" / "summary.csv").exists()


def test_an_unknown_format_is_a_usage_error(inputs, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit:
        cli.main(["batch", str(inputs["sphere"]), "-o", str(tmp_path / "out"), "--format", ".stl"])
    assert exit.value.code == 2 and "invalid choice: '.stl'" in capsys.readouterr().err
