"""``bitemesh mesh --dimension K`` (issue 36): a point table of K columns (and K more for the normals) meshed in K
dimensions through the same front door, the RBF partition of unity fitting the points in K-D, written to .npz; what
cannot be read or written that way refused by name before any work."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli
from bitemesh.cli import build_parser
from bitemesh.cli.mesh import options_of
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.mesh.topology import boundary_facets, euler_characteristic
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain
from bitemesh.io import read_mesh
from bitemesh.meshing import read_input

from tests.cli.commands import assert_one_line_error, save_table
from tests.conftest import DATA
from tests.meshcheck import BALL, largest_facet_circumradius

#: boundary nodes lie on the RBF's f = 0, within this of the unit sphere its 3,000 samples lie on: about h^2 / 2 for
#: samples h = 0.19 apart (a cubic RBF's error between samples on a surface of curvature 1 is of order h^2 / 8)
ON_SPHERE = 0.02


def sphere_samples(k: int, count: int, seed: int = 0) -> np.ndarray:
    points = np.random.default_rng(seed).normal(size=(count, k))
    return points / np.linalg.norm(points, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def ball_table(tmp_path_factory):
    """A 4-D sphere's 3,000 samples with their normals, 8 columns."""
    points = sphere_samples(4, 3000)
    return save_table(tmp_path_factory.mktemp("dimension") / "ball4.txt", points, points)


@pytest.fixture(scope="module")
def ball_mesh(ball_table):
    output = ball_table.with_name("ball4.npz")
    assert cli.main(["mesh", str(ball_table), "--dimension", "4", "--cells", "4000", "-o", str(output)]) == 0
    return read_mesh(output)


def test_a_4_d_table_is_meshed_as_the_4_ball(ball_mesh):
    """A valid 4-D domain: a ball (domain Euler characteristic 1) bounded by one S^3 (0), its boundary nodes on the
    sphere, its measure between that of the ball through them and that of the ball its facets' circumradius r
    leaves inside (each scaled by the nodes' distance from the sphere)."""
    mesh = ball_mesh
    assert mesh.cells.shape[1] == 5 and 2500 <= len(mesh.cells) <= 6000
    assert check_valid_domain(mesh) == []
    assert boundary_euler_characteristic(mesh) == 0 and euler_characteristic(mesh.cells) == 1
    facets = boundary_facets(mesh.cells)
    radii = np.linalg.norm(mesh.points[np.unique(facets)], axis=1)
    assert np.abs(radii - 1).max() <= ON_SPHERE
    volume = signed_measures(mesh.points, mesh.cells).sum()
    r = largest_facet_circumradius(mesh.points[facets])
    assert BALL[4] * (1 - r**2) ** 2 * (1 - ON_SPHERE) ** 4 <= volume <= BALL[4] * (1 + ON_SPHERE) ** 4


def test_naming_the_columns_reads_the_samples_the_dimension_reads(ball_table):
    """--columns x,y,z,w,nx,ny,nz,nw reads the 4-D points and normals --dimension 4 reads, bit for bit (the
    options differ in nothing else, and the same samples and options give the same mesh: tests/core)."""
    arguments = (["mesh", str(ball_table), *flags, "-o", "ball.npz"]
                 for flags in (["--dimension", "4"], ["--columns", "x,y,z,w,nx,ny,nz,nw"]))
    read = [read_input(ball_table, options_of(build_parser().parse_args(given))) for given in arguments]
    assert read[0].points.shape == (3000, 4)
    assert np.array_equal(read[0].points, read[1].points) and np.array_equal(read[0].normals, read[1].normals)


@pytest.mark.parametrize("arguments, names", [
    (["--dimension", "3"], [r"8 columns", r"--dimension 4 reads 8"]),
    (["--dimension", "4", "--columns", "x,y,z,w,nx,ny,nz,nw"], [r"give one"]),
    (["--dimension", "6"], [r"dimension", r"\[2, 5\]", "6"]),
    (["--dimension", "4", "-o", "{tmp}/ball.vtu"], [r"ball\.vtu", r"4-D mesh", r"\.npz"]),
    (["--columns", "x,y,z,w,nx,ny,nz,nw", "-o", "{tmp}/ball.xdmf"], [r"4-D mesh", r"\.npz"]),
])
def test_what_cannot_be_read_or_written_so_is_refused_by_name(arguments, names, ball_table, tmp_path, capsys):
    arguments = [argument.format(tmp=tmp_path) for argument in arguments]
    output = [] if "-o" in arguments else ["-o", str(tmp_path / "ball.npz")]
    code = cli.main(["mesh", str(ball_table), *arguments, *output])
    assert_one_line_error(capsys, code, *names)
    assert not list(tmp_path.iterdir())


def test_labelled_contours_keep_their_three_coordinates(tmp_path, capsys):
    gpfile = DATA / "bivme_patient1_cine" / "guidepoints" / "GPFile_000.txt"
    if not gpfile.is_file():
        pytest.skip(f"{gpfile} is absent")
    code = cli.main(["mesh", str(gpfile), "--dimension", "4", "-o", str(tmp_path / "heart.npz")])
    assert_one_line_error(capsys, code, r"labelled contours", r"3 coordinates", r"leave --dimension out")
