"""``bitemesh fem MESH`` and ``bitemesh quality MESH --fem``: the solver check's figures, and one-line refusals that
name the file."""
from __future__ import annotations

import re

import pytest
from bitemesh import cli
from bitemesh.core.fem.check import fem_check
from bitemesh.io import read_mesh, write_mesh

from tests.builders import square_mesh
from tests.cli.commands import assert_no_traceback, assert_one_line_error


def condition_printed(stdout: str, matrix: str = "laplace") -> float:
    match = re.search(rf"^{matrix} K\s+cond (\S+)\s", stdout, re.MULTILINE)
    assert match, stdout
    return float(match.group(1))


def test_fem_prints_the_figures(reference, capsys):
    assert cli.main(["fem", str(reference)]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    mesh = read_mesh(reference)
    report = fem_check(mesh)
    assert out.startswith(f"fem mesh                    {len(mesh.cells)} tetrahedra, ")
    assert condition_printed(out) == pytest.approx(report.laplace.condition, rel=1e-3)
    assert condition_printed(out, "elasticity") == pytest.approx(report.elasticity.condition, rel=1e-3)
    for text in ("D^-1/2 K D^-1/2", "-laplace u = 1, u|bd = 0", "cg+jacobi", "stiffest cells"):
        assert text in out
    listed = re.findall(r"^  cell (\d+) ", out, re.MULTILINE)
    assert [int(index) for index in listed] == [cell.index for cell in report.stiff_cells]


def test_fem_options_reach_the_check(reference, capsys):
    assert cli.main(["fem", str(reference), "--no-elasticity", "--worst", "2"]) == 0
    out, _ = capsys.readouterr()
    assert "elasticity" not in out and len(re.findall(r"^  cell ", out, re.MULTILINE)) == 2


def test_quality_with_fem_prints_both(reference, capsys):
    assert cli.main(["quality", str(reference), "--fem", "--worst", "1"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    assert out.startswith("mesh            ") and "defects: none" in out
    assert out.index("defects: none") < out.index("laplace K") and len(re.findall(r"^  cell ", out, re.MULTILINE)) == 1


def test_fem_refuses_what_is_not_a_tetrahedral_mesh(tmp_path, capsys):
    garbage = tmp_path / "garbage.vtu"
    garbage.write_text("not a mesh\n")
    assert_one_line_error(capsys, cli.main(["fem", str(garbage)]), "garbage.vtu", "cannot read")
    assert_one_line_error(capsys, cli.main(["fem", str(tmp_path / "none.vtu")]), "none.vtu", "does not exist")
    flat = tmp_path / "square.vtu"
    write_mesh(square_mesh(), flat)
    assert_one_line_error(capsys, cli.main(["fem", str(flat)]), "square.vtu", "needs tetrahedra", "triangles",
                          "volume mesh")


def test_fem_refuses_a_flat_cell_and_a_bad_parameter(reference, tmp_path, capsys):
    mesh = read_mesh(reference)
    points = mesh.points.copy()
    points[mesh.cells[0, 3]] = points[mesh.cells[0, :3]].mean(axis=0)   # cell 0 flattened onto its facet
    flat = tmp_path / "flat.vtu"
    write_mesh(type(mesh)(points, mesh.cells), flat)
    assert_one_line_error(capsys, cli.main(["fem", str(flat)]), "flat.vtu", "zero volume", "cell 0",
                          "bitemesh quality")
    assert_one_line_error(capsys, cli.main(["fem", str(reference), "--poisson", "0.5"]), "poisson", r"0\.5",
                          r"\(-1, 0\.5\)")
