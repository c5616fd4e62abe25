"""Cancellation (the pipeline raises Cancelled from its progress callback; Ctrl-C exits 130 with one line) and the
progress bar (percentages, no trace of a longer message, shown only when a step is slow, on stderr)."""
from __future__ import annotations

import io

import numpy as np
import pytest
from bitemesh import cli, meshing
from bitemesh.cli import mesh as mesh_command
from bitemesh.cli import options as cli_options
from bitemesh.cli.options import ProgressBar
from bitemesh.core.sources import points as pipeline
from bitemesh.core.errors import Cancelled
from bitemesh.core.parameters import BitingParameters, ImplicitParameters

from tests.cli.commands import assert_no_traceback

# --------------------------------------------------------------------------------------------- cancellation


@pytest.mark.parametrize("after", [0.0, 0.3, 0.5, 0.75])
def test_pipeline_cancels_with_cancelled(after, inputs):
    points = np.loadtxt(inputs["xyz+normals"])
    seen, calls_after = [], []

    def progress(fraction, message=""):
        if seen and seen[-1][0] > after:
            calls_after.append(fraction)  # called again after it raised: someone swallowed Cancelled
        seen.append((fraction, message))
        assert 0.0 <= fraction <= 1.0
        if fraction > after:
            raise Cancelled("stop")
    with pytest.raises(Cancelled) as raised:
        pipeline.run(points[:, :3], points[:, 3:], ImplicitParameters(), BitingParameters(cells=2000),
                     progress=progress)
    assert type(raised.value) is Cancelled
    assert calls_after == [] and seen[-1][0] > after


def test_progress_reaches_one_in_order(inputs):
    points = np.loadtxt(inputs["xyz+normals"])
    fractions = []
    pipeline.run(points[:, :3], points[:, 3:], ImplicitParameters(), BitingParameters(cells=2000),
                 progress=lambda fraction, message="": fractions.append(fraction))
    assert fractions[-1] == 1.0 and fractions == sorted(fractions) and len(fractions) >= 5


@pytest.mark.parametrize("command", ["mesh", "demo"])
@pytest.mark.parametrize("stop", [KeyboardInterrupt, Cancelled])
def test_interrupt_exits_130(command, stop, inputs, tmp_path, monkeypatch, capsys):
    def interrupted(*args, progress=None, **kwargs):
        progress(0.5, "biting")
        raise stop()
    monkeypatch.setattr(meshing, "run", interrupted)   # the mesh command's and the die demo's
    output = tmp_path / "out.vtu"
    argv = ["mesh", str(inputs["xyz+normals"])] if command == "mesh" else ["demo"]
    code = cli.main(argv + ["-o", str(output)])
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 130
    assert err.strip().splitlines()[-1] == "bitemesh: cancelled"
    assert not output.exists()


# --------------------------------------------------------------------------------------------- progress bar


def terminal_view(text: str) -> list:
    """What a terminal shows for ``text``: each carriage return goes back to column 0 and overwrites."""
    rows = []
    for line in text.split("\n"):
        row = ""
        for part in line.split("\r"):
            row = part + row[len(part):]
        rows.append(row)
    return rows


def test_progress_bar_draws_percentages_and_ends_the_line():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0, width=20)
    for fraction, message in [(0.0, "fit"), (0.25, "sampling"), (0.25, "sampling"), (0.5, "biting"), (1.0, "done")]:
        bar(fraction, message)
    bar.close()
    text = stream.getvalue()
    assert text.startswith("\r[") and text.endswith("\n") and text.count("\n") == 1
    assert text.count("\r") == 4  # the repeated (0.25, "sampling") is not redrawn
    for percent in ("  0%", " 25%", " 50%", "100%"):
        assert percent in text
    assert "[#####               ]  25% sampling" in text
    assert terminal_view(text)[0].rstrip() == "[####################] 100% done"


def test_a_note_while_the_bar_draws_gets_a_line_of_its_own(capsys):
    """A note or a warning printed while the bar is drawn ends the bar's line first (they were appended to the
    bar's line), and the bar goes on below it."""
    import logging
    import warnings

    from bitemesh.cli import _Notes, _show_warning
    bar = ProgressBar(delay=0, width=10)
    bar(0.3, "fitting")
    _Notes().emit(logging.LogRecord("bitemesh", logging.INFO, "", 0, "merged 3 points", None, None))
    bar(0.6, "biting")
    _show_warning(warnings.WarningMessage("the optimiser could not", UserWarning, "", 0).message, UserWarning, "", 0)
    bar(1.0, "done")
    bar.close()
    lines = terminal_view(capsys.readouterr().err)
    assert [line.split("]")[0] if line.startswith("[") else line for line in lines if line] == [
        "[###       ", "bitemesh: note: merged 3 points", "[######    ",
        "bitemesh: warning: the optimiser could not", "[##########"]


def test_progress_bar_leaves_no_trace_of_a_longer_message():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0)
    bar(0.3, "sampling f on 157 x 157 x 157 nodes")
    bar(0.5, "biting")
    bar.close()
    assert terminal_view(stream.getvalue())[0].rstrip() == f"[{'#' * 15}{' ' * 15}]  50% biting"


def test_progress_bar_waits_for_the_delay(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(cli_options, "time", type("FakeTime", (), {"perf_counter": staticmethod(lambda: clock[0])}))
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=1.0)
    bar(0.2, "fit")
    clock[0] += 0.9
    bar(0.4, "sampling")
    assert stream.getvalue() == ""  # fast so far: nothing
    clock[0] += 0.2  # the step has now taken 1.1 s
    bar(0.6, "biting")
    assert " 60% biting" in stream.getvalue()
    clock[0] += 5
    bar(0.8, "repairing")
    bar.close()
    assert " 80% repairing" in stream.getvalue() and stream.getvalue().endswith("\n")


def test_progress_bar_prints_nothing_for_a_fast_run():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=1.0)
    for step in range(11):
        bar(step / 10, "step")
    bar.close()
    assert stream.getvalue() == ""


def test_mesh_shows_the_bar_on_stderr_when_slow(inputs, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(mesh_command, "ProgressBar", lambda: ProgressBar(delay=0))  # every step counts as slow
    assert cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(tmp_path / "s.vtu"), "--radius", "0.4"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert "\r[" in err and "100%" in err and err.endswith("\n")
    assert "\r" not in out and "[#" not in out  # the bar stays off stdout, which holds the report
