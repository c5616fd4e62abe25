"""Awkward parameters and meshes: parameters out of range named at once, the memory hint that fits, a grid over
the free memory, a missing output folder, NaN rows; the API names its bad argument; ``bitemesh quality`` reports
defects instead of repairing them.

Input as users bring it: every awkward input ends in a mesh that follows the data, or in exit 1 with a message
that names the cause.  Never a silently wrong mesh, never a traceback, never a lost file.  Each case builds its own
variant of a small sphere (``unit_sphere_samples``: 1,500 points, radius 1, tests/cli/conftest.py); a mesh counts as
following the data when it is a valid domain, its volume is that of the shape within the chord error of ~3,000 cells
(3 %), and the fidelity check passed (its line is printed).
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import BitingParameters
from bitemesh.io import write_mesh

from tests.cli.commands import assert_refused, mesh_cli, write_rows

# --- parameters out of range ----------------------------------------------------------------------------------

@pytest.mark.parametrize("options, words", [
    (["--grid-spacing", "5"], ["grid_spacing 5", "quarter of the data's longest side", "grid_spacing <="]),
    (["--radius", "1e-5"], ["radius >= ", "max_memory_mb"]),
    (["--radius", "inf"], ["radius must be a finite number"]),
    (["--radius", "50"], ["radius must be in", "cannot exceed"]),
    (["--cells", "10"], ["cells must be in [100"]),
    (["--threshold", "2"], ["threshold must be in [0, 1], got 2"]),
    (["--far-samples", "-1"], ["far_samples must be in [0, 100]"]),
    (["--outliers", "maybe"], []),
    (["--threads", "0"], ["threads (--threads) must be a whole number in [1, ", "got 0",
                          "leave it unset to use every core"]),
    (["--cells", "50000", "--radius", "0.2"], ["--radius 0.2 and --cells 50000", "give one of them"]),
])
def test_parameters_out_of_range_are_named_at_once(capsys, tmp_path, unit_sphere_samples, options, words):
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    output = tmp_path / "out.vtu"
    try:
        code = cli.main(["mesh", str(path), "-o", str(output), *options])
    except SystemExit as usage:   # argparse refuses a choice that is not one
        code = usage.code
    _, err = capsys.readouterr()
    assert code in (1, 2) and "Traceback" not in err
    for word in words:
        assert word in err, err


def test_the_memory_hint_fits(capsys, tmp_path, unit_sphere_samples):
    """The radius the memory refusal suggests is accepted at the same memory bound."""
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--radius", "0.001", "--max-memory-mb", "64")
    assert code == 1
    suggested = float(err.split("radius >= ")[1].split()[0])
    from bitemesh.core.sources.points import run
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters
    result = run(unit_sphere_samples[0], None, ImplicitParameters(max_memory_mb=64), BitingParameters(radius=suggested),
                 optimize=OptimizeParameters(optimize=0))   # the hint is the grid's: the optimizer only adds time
    assert result.mesh.cells.size


def test_a_grid_over_the_free_memory_is_refused_in_a_moment(monkeypatch, capsys, tmp_path, unit_sphere_samples):
    """--max-memory-mb above what the machine has: the machine's free memory bounds the grid, before the fit."""
    import time

    import bitemesh.core.grid.sampled as grid
    import bitemesh.core.steps.spine as spine
    for module in (grid, spine):
        monkeypatch.setattr(module, "available_memory_mb", lambda: 500.0)
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    clock = time.perf_counter()
    code, _, err, _ = mesh_cli(capsys, tmp_path, path, "--grid-spacing", "0.004", "--max-memory-mb", "1000000")
    assert time.perf_counter() - clock < 5
    assert_refused(code, err, "the 500 MiB of memory this machine has free", "grid_spacing >= ")


def test_a_missing_output_folder_is_refused_before_any_work(capsys, tmp_path, unit_sphere_samples):
    path = write_rows(tmp_path / "cloud.xyz", unit_sphere_samples[0])
    code = cli.main(["mesh", str(path), "-o", str(tmp_path / "absent" / "out.vtu")])
    _, err = capsys.readouterr()
    assert_refused(code, err, "does not exist")


def test_nan_rows_are_named_by_their_line(capsys, tmp_path, unit_sphere_samples):
    points = unit_sphere_samples[0].copy()
    points[4, 2] = np.nan
    path = write_rows(tmp_path / "cloud.xyz", points, header=["x", "y", "z"])
    code, _, err, _ = mesh_cli(capsys, tmp_path, path)
    assert_refused(code, err, "NaN", "line 6")


# --- the API names its arguments ------------------------------------------------------------------------------

@pytest.mark.parametrize("points, normals, words", [
    (np.array([["a", "b", "c"]] * 20), None, ["points must be"]),
    (np.zeros((20, 6)), None, ["points must be an (n, k) array", "(2, 3, 4, 5)"]),
    ("sphere", "wrong shape", ["normals must have the shape of points"]),
    ("sphere", "zeros", ["normals", "zero-length"]),
])
def test_the_api_names_the_bad_argument(unit_sphere_samples, points, normals, words):
    import bitemesh
    if isinstance(points, str):
        points = unit_sphere_samples[0]
    normals = {"wrong shape": np.ones((5, 3)), "zeros": np.zeros_like(points), None: None}[normals]
    with pytest.raises(bitemesh.InvalidInputError) as caught:
        bitemesh.mesh(bitemesh.Samples(points, normals), cells=1000)
    for word in words:
        assert word in str(caught.value)


# --- bitemesh quality reports defects ------------------------------------------------------------------------

def small_mesh(unit_sphere_samples):
    from bitemesh.core.sources.points import run
    return run(*unit_sphere_samples, biting=BitingParameters(cells=1500)).mesh


@pytest.mark.parametrize("defect, words", [
    ("inverted", ["inverted cells"]),
    ("duplicated", ["cells with the same vertices as another cell"]),
    ("flat", ["flat cells"]),
    ("unused", ["points used by no cell"]),
])
def test_quality_reports_defects_instead_of_repairing_them(capsys, tmp_path, unit_sphere_samples, defect, words):
    mesh = small_mesh(unit_sphere_samples)
    points, cells = mesh.points, mesh.cells.copy()
    if defect == "inverted":
        cells[:100, :2] = cells[:100, 1::-1]
    elif defect == "duplicated":
        cells = np.vstack([cells, cells])
    elif defect == "flat":
        points = np.vstack([points, points[cells[0, :3]].mean(axis=0)])
        cells = np.vstack([cells, [[cells[0, 0], cells[0, 1], cells[0, 2], len(points) - 1]]])
    else:
        points = np.vstack([points, [[9.0, 9.0, 9.0]]])
    path = tmp_path / "defective.vtu"
    write_mesh(Mesh(points, cells), path)
    code = cli.main(["quality", str(path)])
    out, err = capsys.readouterr()
    assert code == 1 and "defects:" in out and "Traceback" not in err
    for word in words:
        assert word in out


def test_quality_of_a_truncated_file_says_why(capsys, tmp_path, unit_sphere_samples):
    path = tmp_path / "mesh.vtu"
    write_mesh(small_mesh(unit_sphere_samples), path)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    code = cli.main(["quality", str(path)])
    _, err = capsys.readouterr()
    assert_refused(code, err, "mesh.vtu", "truncated")


@pytest.mark.parametrize("option, flag", [({"label": 2}, "--label 2"), ({"domain": "EPI - LV_ENDO"}, "--domain"),
                                          ({"frame": 1}, "--frame")])
def test_an_option_for_another_kind_of_input_is_refused_naming_it(unit_sphere_samples, option, flag):
    """Options given for scattered points that apply to label maps or labelled contours are refused, not ignored."""
    import bitemesh
    points, normals = unit_sphere_samples
    with pytest.raises(bitemesh.InvalidInputError, match=rf"^{flag} applies to (label maps|labelled contours)"):
        bitemesh.mesh(bitemesh.Samples(points, normals), cells=1000, **option)
