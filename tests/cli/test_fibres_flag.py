"""``--fibres`` of ``bitemesh mesh`` and ``bitemesh demo heart``: the fibres written as cell vectors of a heart mesh
(the tagged two-cavity shell stands in for the meshing, which other tests cover), and one-line refusals: a mesh
without the heart's surfaces, an output that would drop them, the die, an angle out of range."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli, meshing
from bitemesh.cli import demo as demo_command
from bitemesh.cli import mesh as mesh_command
from bitemesh.core.fem.fibres import FIBRE_ARRAYS, fibre_field
from bitemesh.core.steps.spine import MeshingResult
from bitemesh.io import read_mesh

from tests.cli.commands import assert_no_traceback, assert_one_line_error
from tests.fibrecheck import tagged_shell


def shell_result(*args, **kwargs) -> MeshingResult:
    mesh = tagged_shell()
    return MeshingResult(mesh=mesh, implicit=None, nodes=mesh.points, radius=7.4, seconds={"meshing": 1.0})


def meshed_as_the_shell(monkeypatch):
    """The front door meshes any input as the tagged shell: labelled contours whose meshing returns it."""
    monkeypatch.setattr(meshing, "read_input", lambda input, options: meshing.Samples(
        np.zeros((1, 3)), labels=np.array(["EPI"])))
    monkeypatch.setattr(meshing, "run_labelled", shell_result)


def forbidden(*args, **kwargs):
    raise AssertionError("meshed before the options were checked")


def check_written(path, out):
    mesh = read_mesh(path)
    expected = fibre_field(tagged_shell())
    for name, values in zip(FIBRE_ARRAYS, (expected.fibre, expected.sheet, expected.sheet_normal,
                                           expected.helix_angle)):
        assert np.allclose(mesh.cell_data[name], values, rtol=0, atol=1e-12), name
    assert "fibres: cell arrays Fibre, Sheet, SheetNormal, HelixAngle" in out and "point arrays Psi" in out
    if str(path).endswith((".vtu", ".vtk", ".xdmf")):   # the Laplace solutions, where point arrays are kept
        np.testing.assert_array_equal(mesh.point_data["Psi"], expected.laplace["Psi"])
    assert "  fibres " in out.split("time per step:")[1]


def test_mesh_fibres_writes_the_fibres_as_cell_vectors(tmp_path, monkeypatch, capsys):
    meshed_as_the_shell(monkeypatch)
    output = tmp_path / "heart.vtu"
    assert cli.main(["mesh", "contours.txt", "-o", str(output), "--fibres", "--alpha-endo", "40"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    check_written(output, out)


def test_demo_heart_fibres_writes_the_fibres(tmp_path, monkeypatch, capsys):
    meshed_as_the_shell(monkeypatch)
    output = tmp_path / "heart.vtk"
    assert cli.main(["demo", "heart", "--fibres", "-o", str(output)]) == 0
    check_written(output, capsys.readouterr()[0])


def test_fibres_of_scattered_points_are_refused_naming_the_missing_surfaces(inputs, tmp_path, capsys):
    output = tmp_path / "sphere.vtu"
    code = cli.main(["mesh", str(inputs["xyz+normals"]), "-o", str(output), "--cells", "2000", "--no-optimize",
                     "--fibres"])
    _, err = capsys.readouterr()
    assert_no_traceback(err)
    last = err.strip().splitlines()[-1]   # after the notes and the progress bar of the meshing
    assert code == 1 and last.startswith("bitemesh: error: fibres (--fibres): "), err
    assert "has no EPI, LV_ENDO, RV_ENDO, BASE" in last and "mesh labelled heart contours" in last
    assert not output.exists()


@pytest.mark.parametrize("argv, names", [
    (["mesh", "in.txt", "-o", "{}/m.msh", "--fibres"], [r"--fibres: a \.msh file keeps no cell arrays", r"\.vtu"]),
    (["mesh", "in.txt", "-o", "{}/m.vtu", "--fibres", "--alpha-epi", "-100"], [r"alpha_epi", r"-100"]),
    (["demo", "heart", "-o", "{}/m.inp", "--fibres"], [r"--fibres: a \.inp file"]),
    (["demo", "die", "-o", "{}/m.vtu", "--fibres"], [r"--fibres: the die has no myocardium", r"demo heart"]),
], ids=["msh", "angle", "demo-inp", "demo-die"])
def test_fibres_options_are_refused_before_any_work(argv, names, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(mesh_command, "mesh", forbidden)
    monkeypatch.setattr(demo_command, "mesh_heart", forbidden)
    monkeypatch.setattr(demo_command, "mesh_die", forbidden)
    assert_one_line_error(capsys, cli.main([part.format(tmp_path) for part in argv]), *names)
