"""The solvers on bitemesh's files, as their users load them: the cardiac-geometries / fenicsx-pulse folder (an
output without an extension) read back by bitemesh and by cardiac-geometries' ``Geometry.from_folder`` in DOLFINx
(the PyPI wheel dolfinx-solver-real), its markers handed to fenicsx-ldrb by cardiac-geometries'
``transform_markers`` unchanged; the .xdmf with bitemesh's fibres read in DOLFINx and compared with ldrb's.  The
solver part runs in the Python named by $BITEMESH_SOLVER_PYTHON (a Python 3.12 or later with dolfinx-solver-real,
cardiac-geometriesx and fenicsx-ldrb; .ci/solver-venv makes one), tests/solvers/solver_check.py."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from bitemesh import cli, meshing
from bitemesh.core.fem.landmarks import landmarks
from bitemesh.core.mesh.simplicial import facet_measures
from bitemesh.io import read_mesh, write_mesh

from tests.cli.commands import assert_one_line_error
from tests.cli.test_fibres_flag import forbidden
from tests.fibrecheck import tagged_shell
from tests.io.test_tagged_files import facet_set

SOLVER = os.environ.get("BITEMESH_SOLVER_PYTHON")


def left_ventricle():
    """The tagged shell with its RV cavity's surface left out and LV_ENDO named ENDO (numbers as bitemesh gives an
    LV: EPI 7, ENDO 6, BASE 5, MYOCARDIUM 8)."""
    mesh = tagged_shell()
    keep = mesh.facet_tags != mesh.tag_names["RV_ENDO"][0]
    renumber = np.zeros(5, np.int32)
    renumber[[1, 2, 4]] = [7, 6, 5]
    return mesh.with_tags(mesh.facets[keep], renumber[mesh.facet_tags[keep]],
                          {"EPI": (7, 2), "ENDO": (6, 2), "BASE": (5, 2), "MYOCARDIUM": (8, 3)},
                          np.full(len(mesh.cells), 8, np.int32))


@pytest.mark.parametrize("make", [tagged_shell, left_ventricle], ids=["biventricular", "left ventricle"])
def test_the_folder_reads_back(tmp_path, make):
    mesh = make()
    write_mesh(mesh, tmp_path / "heart")
    assert sorted(path.name for path in (tmp_path / "heart").iterdir()) == ["info.json", "markers.json", "mesh.h5",
                                                                          "mesh.xdmf"]
    back = read_mesh(tmp_path / "heart")
    np.testing.assert_array_equal(back.points, mesh.points)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    np.testing.assert_array_equal(back.cell_data["Region"], mesh.cell_data["Region"])
    assert facet_set(back.facets, back.facet_tags) == facet_set(mesh.facets, mesh.facet_tags)
    assert back.tag_names == mesh.tag_names
    assert json.loads((tmp_path / "heart" / "info.json").read_text())["unit"] == "mm"


def test_fibres_or_coordinates_into_a_folder_are_refused_before_meshing(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(meshing, "read_input", forbidden)
    for flag, words in (("--fibres", ("--fibres", "cardiac-geometries folder", ".xdmf")),
                        ("--coordinates", ("--coordinates", "cardiac-geometries folder", ".xdmf"))):
        code = cli.main(["mesh", "contours.txt", "-o", str(tmp_path / "heart"), flag])
        assert_one_line_error(capsys, code, *words)


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    """What the solvers found (tests/solvers/solver_check.py, one process) in the shell's folder, a left
    ventricle's folder and the shell's .xdmf with bitemesh's fibres: {"biventricular": ..., "left ventricle": ...,
    "xdmf": ...}."""
    if not SOLVER:
        pytest.skip("no solver Python: set BITEMESH_SOLVER_PYTHON (see .ci/run)")
    from bitemesh.core.fem.fibres import with_fibres
    folder = tmp_path_factory.mktemp("solvers")
    targets = {"biventricular": folder / "biventricular", "left ventricle": folder / "left_ventricle",
               "xdmf": folder / "heart.xdmf"}
    write_mesh(tagged_shell(), targets["biventricular"])
    write_mesh(left_ventricle(), targets["left ventricle"])
    write_mesh(with_fibres(tagged_shell())[0], targets["xdmf"])
    done = subprocess.run([SOLVER, str(Path(__file__).with_name("solver_check.py")), *map(str, targets.values())],
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    return {name: found[str(path)] for name, path in targets.items()}


@pytest.mark.parametrize("make", [tagged_shell, left_ventricle], ids=["biventricular", "left ventricle"])
def test_cardiac_geometries_loads_the_folder_and_ldrb_takes_its_markers(solved, make):
    """The same cells, tags and names (biventricular: with cardiac-geometries' LV and RV beside LV_ENDO and
    RV_ENDO), the volume and every surface's area as bitemesh measures them (to 1e-9), unit ldrb fibres."""
    mesh = make()
    found = solved["biventricular" if make is tagged_shell else "left ventricle"]
    names = {name: list(value) for name, value in mesh.tag_names.items()}
    if "RV_ENDO" in names:
        names.update(LV=names["LV_ENDO"], RV=names["RV_ENDO"])
    edges, edge_tags, vertices, vertex_tags, landmark_names = landmarks(mesh)
    names.update({name: list(value) for name, value in landmark_names.items()})
    assert found["markers"] == names
    assert found["edge_counts"] == {str(tag): int(np.sum(edge_tags == tag)) for tag in set(edge_tags.tolist())}
    assert found["vertex_counts"] == {str(tag): 1 for tag in vertex_tags.tolist()}
    assert found["cells"] == len(mesh.cells) and found["cell_tags"] == sorted(set(mesh.cell_data["Region"]))
    areas = facet_measures(mesh.points[mesh.facets])
    for name, (tag, dimension) in mesh.tag_names.items():
        if dimension == 2:
            assert found["facet_counts"][str(tag)] == np.sum(mesh.facet_tags == tag)
            assert found["areas"][name] == pytest.approx(areas[mesh.facet_tags == tag].sum(), rel=1e-9)
    assert found["volume"] == pytest.approx(mesh.cell_data["Volume"].sum(), rel=1e-9)
    assert found["ldrb"]["unit"] < 1e-12


def test_ldrb_on_the_xdmf_agrees_with_bitemeshs_fibres(solved):
    """The shell's .xdmf with bitemesh's fibres, read in DOLFINx as docs/solvers.md shows, its Fibre found in the
    HDF5 file by name (/CellData/Fibre); ldrb with the same angles on DG0: the two implement the same rule and differ
    in where it is evaluated (ldrb on its own P1 gradients per cell, bitemesh on gradients recovered at the nodes).
    Across walls two to three cells thick the helix angle turns 90 degrees, so half a cell apart is up to 15-20
    degrees: the median within 10, 90 % within 20 (measured 4.5 and 16.6; 3.8 and 13.5 on the 20,000-cell heart)."""
    found = solved["xdmf"]
    assert found["cells"] == len(tagged_shell().cells)
    assert found["median"] <= 10 and found["p90"] <= 20, found
