"""``bitemesh mesh FRAME ... --space-time`` (issue 36): the frames of a cycle meshed as one 4-D space-time mesh, written
to .npz or .h5 with each frame's instant cut out of it as a ParaView time series beside it."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from xml.etree import ElementTree

import numpy as np
import pytest

from bitemesh import cli, mesh
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.mesh.validity import check_valid_domain, count_boundary_components
from bitemesh.io import read_mesh

from tests import builders
from tests.cli.commands import save_table

#: a ball breathing through a cycle of four frames: its radius a frame
RADII = (1.0, 1.1, 1.05, 0.95)
#: R of the space-time mesh (a frame two R apart along time)
RADIUS = 0.3


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """The breathing ball's frames as scattered points with normals, one .xyz file a frame."""
    folder = tmp_path_factory.mktemp("frames")
    points, normals = builders.sphere_samples(0.1, seed=2)
    return [str(save_table(folder / f"frame_{number}.xyz", radius * points, normals))
            for number, radius in enumerate(RADII)]


@pytest.fixture(scope="module")
def meshed(frames, tmp_path_factory):
    """The cycle meshed once by the command: its output path and what it printed."""
    import contextlib
    import io
    output = tmp_path_factory.mktemp("cycle") / "cycle.npz"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert cli.main(["mesh", *frames, "--space-time", "--radius", str(RADIUS), "-o", str(output)]) == 0
    return output, printed.getvalue()


def test_the_frames_are_one_valid_4_d_mesh_whose_instants_are_the_frames(frames, meshed):
    """One valid 4-D domain (every 3-face in one or two cells, a manifold boundary, positive cells), read back from
    the .npz; each frame's instant a valid 3-D mesh of one boundary whose volume is that of the frame's own 3-D mesh
    at the same R within 3 % (the issue's bound; both lose about (R / r)^2 / 2 of the ball, 4-5 % here, to their
    chords): f is Catmull-Rom's cubic in time, sampled by nodes R apart, two R a frame, so the instant cuts the
    corner of the motion at a frame by about f'' (R / 2)^2 / 2: 0.005 in radius where the ball turns (1.5 %)."""
    output, printed = meshed
    space_time = read_mesh(output)
    assert space_time.points.shape[1] == 4 and space_time.cells.shape[1] == 5
    assert check_valid_domain(space_time) == []
    series = ElementTree.parse(output.with_suffix(".pvd")).getroot()
    files = [entry.get("file") for entry in series.iter("DataSet")]
    assert files == [f"cycle_{number:03d}.vtu" for number in range(len(RADII))]
    for name, frame in zip(files, frames):
        instant = read_mesh(output.with_name(name))
        assert [p for p in check_valid_domain(instant) if "flat cells" not in p] == []
        assert count_boundary_components(instant) == 1
        alone = mesh(frame, radius=RADIUS, optimize=0).mesh
        ratio = signed_measures(instant.points, instant.cells).sum() / signed_measures(alone.points, alone.cells).sum()
        assert ratio == pytest.approx(1.0, abs=0.03), name
    assert re.search(r"wrote .*cycle\.pvd: each frame's instant", printed)


def test_several_inputs_without_space_time_are_refused_naming_it(frames, tmp_path, capsys):
    assert cli.main(["mesh", *frames[:2], "-o", str(tmp_path / "mesh.vtu")]) != 0
    error = capsys.readouterr().err
    assert "2 inputs given" in error and "--space-time" in error and "bitemesh batch" in error


@pytest.mark.parametrize("argv, message", [
    (["-o", "cycle.vtu"], r"space-time mesh of 3-D frames is 4-D: .*\.npz or \.h5"),
    (["-o", "cycle.npz", "--fibres"], r"--fibres applies to a 3-D heart mesh, not to a space-time mesh"),
    (["-o", "cycle.npz", "--frame-step", "0"], r"frame_step must be in \(0, inf\], got 0"),
])
def test_what_a_space_time_mesh_cannot_be_is_refused_before_any_work(frames, tmp_path, capsys, argv, message):
    argv = [str(tmp_path / arg) if arg.startswith("cycle") else arg for arg in argv]
    assert cli.main(["mesh", *frames, "--space-time", *argv]) != 0
    assert re.search(message, capsys.readouterr().err)


def test_a_frame_step_without_space_time_is_refused_not_ignored(frames, tmp_path, capsys):
    assert cli.main(["mesh", frames[0], "--frame-step", "0.5", "-o", str(tmp_path / "ball.vtu")]) != 0
    assert "--frame-step 0.5 applies to a space-time mesh of several frames; add --space-time" in \
        capsys.readouterr().err


def test_one_frame_is_no_cycle(frames, tmp_path, capsys):
    assert cli.main(["mesh", frames[0], "--space-time", "-o", str(tmp_path / "cycle.npz")]) != 0
    assert "a cycle needs at least 2 frames, got 1" in capsys.readouterr().err


def test_a_frame_that_cannot_be_read_is_named_by_its_number(frames, tmp_path, capsys):
    missing = str(tmp_path / "frame_9.xyz")
    assert cli.main(["mesh", frames[0], missing, "--space-time", "-o", str(tmp_path / "cycle.npz")]) != 0
    assert f"space_time: frame 1 ({missing}): cannot read points" in capsys.readouterr().err


def test_the_example_draws_each_instant_asked_in_its_own_panel(meshed, tmp_path):
    """examples/space_time_heart.py on the command's .pvd: one panel an instant, each with the instant drawn (pixels
    of the wall's colour in every panel), the frames listed; a frame the series lacks is named."""
    from tests.vtk.test_examples import ROOT, read_png, run_example
    output, _ = meshed
    picture = tmp_path / "instants.png"
    script = ROOT / "examples" / "space_time_heart.py"
    done = run_example(str(output.with_suffix(".pvd")), "-o", str(picture), "--frames", "0", "1", "3", script=script)
    assert [line.split(":")[0] for line in done.stdout.splitlines()[:3]] == ["frame 0", "frame 1", "frame 3"]
    pixels = read_png(picture)[..., :3].astype(int)
    wall = (pixels[..., 0] - pixels[..., 2] > 60)   # the wall's red against the white background
    panels = np.array_split(wall, 3, axis=1)
    assert all(panel.mean() > 0.05 for panel in panels), [panel.mean() for panel in panels]
    refused = subprocess.run([sys.executable, str(script), str(output.with_suffix(".pvd")), "--frames", "7"],
                             capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT / "filters")})
    assert refused.returncode != 0 and "--frames 7: the series has frames 0 to 3" in refused.stderr
