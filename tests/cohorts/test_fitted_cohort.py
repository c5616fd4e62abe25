"""``bitemesh batch --template``: one template fitted to every case on the folder's 2-worker cluster, so that every
output has its cells, and the cohort's shape model (mean and modes) written beside them.

Known answers: ellipsoids whose one semi-axis a varies (1.2, 1.4, 1.6, 1.8; b = 1, c = 0.7, no symmetry axis that
would leave the template free to turn) from an ellipsoid template (a = 1.5) are a one-parameter family,
so the first mode holds all but the fits' own scatter (nodes within 0.05 R of the surface, the issue's bound, against
a mode that moves them by ~0.1 on average: >= 95 % of the variance), and the mean and the mode's meshes at -2 and +2
standard deviations are as long along x as the mean of the fitted cases' lengths and that mean -/+ 2 of their
standard deviations (within 2 %: the shape is linear in a, and the lengths enter the model linearly); on the real
cine frames, the mean heart's LV cavity lies between the cases' smallest and largest."""
from __future__ import annotations

import csv

import numpy as np
import pytest
from bitemesh import batch, cli
from bitemesh.core.mesh.tags import cavity_volumes
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.shapes import ellipsoid_distance
from bitemesh.io import read_mesh
from bitemesh.meshing import Samples, mesh, write

from tests import builders
from tests.cli.commands import assert_one_line_error, save_table
from tests.cohorts.conftest import write_manifest
from tests.meshcheck import assert_valid_domain

LENGTHS = (1.2, 1.4, 1.6, 1.8)
#: the template's semi-axes, and the cases' b and c
TEMPLATE, B, C = (1.5, 1.0, 0.7), 1.0, 0.7


@pytest.fixture(scope="module")
def ellipsoids(tmp_path_factory):
    """(an ellipsoid template of ~1,500 cells, {case: (file of scattered points on the ellipsoid, semi-axes)})."""
    folder = tmp_path_factory.mktemp("ellipsoids")
    points, normals = builders.sphere_samples(0.08, seed=1)
    template = folder / "ellipsoid.vtu"
    normals = normals / np.array(TEMPLATE)   # the normals of the stretched sphere: the inverse transpose
    write(mesh(Samples(points * TEMPLATE, normals / np.linalg.norm(normals, axis=1, keepdims=True)), cells=1500),
          template)
    cases = {}
    for number, length in enumerate(LENGTHS):
        axes = np.array([length, B, C])
        cases[f"a{number}"] = (save_table(folder / f"a{number}.xyz", points * axes), axes)
    return template, cases


def boundary_nodes(points, cells):
    return points[np.unique(boundary_facets(cells))]


def test_every_case_has_the_template_cells_and_the_modes_are_the_family(client, ellipsoids, tmp_path):
    template_path, cases = ellipsoids
    output = tmp_path / "cohort"
    rows = batch([file for file, _ in cases.values()], client=client, output_dir=output, template=template_path)
    assert [row["status"] for row in rows] == ["done"] * len(cases), rows
    template = read_mesh(template_path)
    for name, (_, axes) in cases.items():
        fitted = read_mesh(output / f"{name}.vtu")
        np.testing.assert_array_equal(fitted.cells, template.cells)
        assert_valid_domain(fitted)
        on_surface = ellipsoid_distance(boundary_nodes(fitted.points, fitted.cells), np.zeros(3), axes)
        assert np.abs(on_surface).max() <= 0.05, name
    with open(output / "shape" / "modes.csv", newline="") as stream:
        modes = list(csv.DictReader(stream))
    assert float(modes[0]["explained"]) >= 0.95, modes
    extents = [np.ptp(read_mesh(output / f"{name}.vtu").points[:, 0]) for name in cases]
    middle, spread = np.mean(extents), np.std(extents, ddof=1)
    for name, extent in (("mean", middle), ("mode1_minus2sd", middle - 2 * spread),
                         ("mode1_plus2sd", middle + 2 * spread)):
        shape = read_mesh(output / "shape" / f"{name}.vtu")
        np.testing.assert_array_equal(shape.cells, template.cells)
        # the mode's sign is arbitrary: -2 sd is the shorter or the longer one
        assert min(abs(np.ptp(shape.points[:, 0]) - length) for length in (extent, 2 * middle - extent)) \
            <= 0.02 * middle, name
    assert "Shape model" in (output / "report.html").read_text()

    again = batch([file for file, _ in cases.values()], client=client, output_dir=output, template=template_path)
    assert [row["status"] for row in again] == ["skipped"] * len(cases)
    with open(output / "shape" / "modes.csv", newline="") as stream:
        assert list(csv.DictReader(stream)) == modes


def test_a_fitted_cohort_refuses_mesh_options(client, ellipsoids, tmp_path, capsys):
    template_path, cases = ellipsoids
    files = [str(file) for file, _ in cases.values()]
    code = cli.main(["batch", *files[:2], "-o", str(tmp_path / "out"), "--template", str(template_path),
                     "--cells", "5000"])
    assert_one_line_error(capsys, code, "cells", "--cells", "template", "leave it out")
    code = cli.main(["batch", *files[:2], "-o", str(tmp_path / "out"), "--template", str(files[0])])
    assert_one_line_error(capsys, code, "template", "a0.xyz", ".vtu")
    manifest = write_manifest(tmp_path / "cases.csv", [(files[0], "first", 3)], header=("input", "output", "seed"))
    rows = batch([manifest], client=client, output_dir=tmp_path / "seeded", template=template_path)
    assert rows[0]["status"] == "failed" and "'seed'" in rows[0]["message"] and "frame" in rows[0]["message"]


def test_cine_frames_as_a_cohort(client, cine, tmp_path, capsys):
    """Three frames of the real cycle through the command: every output the template's cells, the wall data close
    (the issue's mean <= 1.0 mm), the mean heart a valid domain whose LV cavity lies between the cases'."""
    folder, template_path = cine
    frames = [folder / "guidepoints" / f"GPFile_{frame:03d}.txt" for frame in (0, 8, 16)]
    output = tmp_path / "cohort"
    assert cli.main(["batch", *map(str, frames), "-o", str(output), "--template", str(template_path),
                     "--scheduler", client.scheduler.address]) == 0
    assert "the shape model in" in capsys.readouterr().out
    with open(output / "summary.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert all(float(row["fidelity"]) <= 1.0 for row in rows), rows
    template = read_mesh(template_path)
    volumes = []
    for row in rows:
        fitted = read_mesh(output / row["output"])
        np.testing.assert_array_equal(fitted.cells, template.cells)
        volumes.append(cavity_volumes(fitted)["LV_ENDO"])
    mean = read_mesh(output / "shape" / "mean.vtu")
    assert_valid_domain(mean)
    assert mean.tag_names == template.tag_names
    assert min(volumes) < cavity_volumes(mean)["LV_ENDO"] < max(volumes)
