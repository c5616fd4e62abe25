"""``bitemesh quality`` (the summary, the histogram picture, one-line errors) and ``bitemesh demo`` (the die, the
shipped biv-me heart)."""
from __future__ import annotations

import pytest
from bitemesh import cli, meshing
from bitemesh.core.mesh.quality import quality_summary, radius_ratio
from bitemesh.core.shapes import die
from bitemesh.io import read_mesh

from tests.cli.commands import assert_no_traceback, assert_one_line_error, mean_q_printed
from tests.meshcheck import assert_valid_domain

# --------------------------------------------------------------------------------------------- quality


def test_quality_prints_the_summary(reference, capsys):
    assert cli.main(["quality", str(reference)]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    mesh = read_mesh(reference)
    assert out.startswith(f"{quality_summary(mesh)}\ndefects: none")
    assert out.startswith(f"mesh            {len(mesh.cells)} tetrahedra, {len(mesh.points)} points\n")
    assert mean_q_printed(out) == pytest.approx(radius_ratio(mesh.points, mesh.cells).mean(), abs=1e-4)
    assert "\ntopology: 1 part(s), 0 handle(s), 0 void(s)" in out   # a ball
    assert "\npoor cells: " in out


def test_quality_names_the_slivers_of_a_valid_mesh(tmp_path, capsys):
    """A valid tetrahedron 0.02 high over a triangle of side about 1 (dihedral angles of a few degrees): no defect,
    but a poor cell, its worst angle and where it is (the report said "no flat cell" and nothing more)."""
    import numpy as np
    from bitemesh.core.mesh.simplicial import Mesh
    from bitemesh.core.optimize.measures import smallest_angles
    from bitemesh.io import write_mesh
    points = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.9, 0], [0.5, 0.3, 0.02]], float)
    path = tmp_path / "sliver.vtu"
    write_mesh(Mesh(points, np.array([[0, 1, 2, 3]])), path)
    assert cli.main(["quality", str(path)]) == 0
    out, _ = capsys.readouterr()
    worst = float(smallest_angles(points, np.array([[0, 1, 2, 3]]))[0])
    assert "defects: none" in out and worst < 5
    assert f"poor cells: 1 with a dihedral angle below 20 degrees or a radius ratio below 0.3 (the optimizer's " \
           f"bounds), the worst {worst:.2f} degrees at (0.5, 0.3, 0.005)" in out


def test_quality_histogram_writes_a_png(reference, tmp_path, capsys):
    picture = tmp_path / "q.png"
    assert cli.main(["quality", str(reference), "--histogram", str(picture), "--bins", "10"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert f"wrote {picture}" in out
    data = picture.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 1000


@pytest.mark.parametrize("target, names", [("missing/q.png", [r"--histogram", "missing"]),
                                            ("q.xyz", [r"--histogram", "q.xyz"])])
def test_quality_histogram_bad_path_is_one_line(target, names, reference, tmp_path, capsys):
    code = cli.main(["quality", str(reference), "--histogram", str(tmp_path / target)])
    assert_one_line_error(capsys, code, *names)


def test_quality_of_a_bad_mesh_is_one_line(tmp_path, capsys):
    garbage = tmp_path / "garbage.vtu"
    garbage.write_text("not a mesh\n")
    assert_one_line_error(capsys, cli.main(["quality", str(garbage)]), "garbage.vtu")
    assert_one_line_error(capsys, cli.main(["quality", str(tmp_path / "none.vtu")]), "none.vtu", "does not exist")


def test_quality_bins_zero_is_one_line(reference, tmp_path, capsys):
    code = cli.main(["quality", str(reference), "--histogram", str(tmp_path / "q.png"), "--bins", "0"])
    _, err = capsys.readouterr()
    assert code == 1 and err.startswith("bitemesh: error: bins") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "q.png").exists()


# --------------------------------------------------------------------------------------------- demo


def test_demo_meshes_the_die(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.build_parser().parse_args(["demo"]).dataset == "die"   # written to die.vtu by default
    code = cli.main(["demo", "-o", "die.vtu"])
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert code == 0, err
    mesh = read_mesh(tmp_path / "die.vtu")
    assert 7000 <= len(mesh.cells) <= 13000
    assert_valid_domain(mesh, euler=2, components=1, mean_quality=0.78, measure=die().measure,
                        measure_tolerance=0.03)
    assert mean_q_printed(out) >= 0.78
    assert "wrote die.vtu" in out and "of the exact die" in out and "time per step:" in out


def test_demo_refuses_a_bad_output_before_work(tmp_path, monkeypatch, capsys):
    def forbidden(*args, **kwargs):
        raise AssertionError("the demo meshed before checking its output")
    monkeypatch.setattr(meshing, "run", forbidden)
    assert_one_line_error(capsys, cli.main(["demo", "-o", str(tmp_path / "die.stl")]), r"\.stl")


def test_demo_heart_meshes_the_shipped_guide_points(tmp_path, capsys):
    output = tmp_path / "heart.vtu"
    assert cli.main(["demo", "heart", "--cells", "20000", "-o", str(output)]) == 0
    assert_valid_domain(read_mesh(output), components=1)
    assert "biv-me" in capsys.readouterr().out
