"""The MeshOptimizer (issue #5): relaxation, sliver removal and the boundary on f = 0, on analytic shapes (no VTK);
its pieces on hand-made configurations: tests/core/optimize/test_optimizer_pieces.py.

Measured on the inputs below (seed 0), before -> after, mean radius ratio Q / smallest dihedral angle: sphere 10,000
cells 0.805 / 0.8 deg -> 0.902 / 32.5 deg; die 10,000 0.795 / 1.3 -> 0.895 / 25.5; torus 6,000 0.792 / 1.4 ->
0.897 / 33.0; two-cavity shell 10,000 0.792 / 0.9 -> 0.890 / 25.7; annulus (2D, 1,000) 0.928 / 29.7 -> 0.978 / 40.0
(smallest interior angle).  The thresholds asserted leave a margin below these.
"""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from bitemesh.core.optimize import optimizer
from bitemesh.core.optimize import relax as relaxation
from bitemesh.core.errors import BitemeshWarning, Cancelled, InvalidInputError, MeshingError
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.optimize.measures import inverse_mean_ratio
from bitemesh.core.optimize.flips import flip
from bitemesh.core.optimize.optimizer import optimize_mesh
from bitemesh.core.optimize.relax import relax, smooth
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid, radius_for_cells
from bitemesh.core.mesh.validity import check_valid_domain
from bitemesh.core.mesh.quality import dihedral_angles, edge_lengths, radius_ratio
from bitemesh.core.shapes import annulus, die, sphere, torus, two_cavity_heart, two_cavity_shell
from bitemesh.core.mesh.topology import boundary_facets, unique_rows

from tests.builders import sampled, volume
from tests.meshcheck import assert_valid_domain

#: the shapes of the issue and their sizes (cells); the grid resolves R / GRID_PER_RADIUS, fine enough that the
#: multilinear f follows the true surface within 0.05 R at the creases of the die and of the shell
SHAPES = {"sphere": (sphere(), 10000), "die": (die(), 10000), "torus": (torus(), 6000),
          "two-cavity shell": (two_cavity_shell(), 10000)}
GRID_PER_RADIUS = 6


def meshed(shape, cells, seed=0):
    """The grid, the unoptimised mesh of the pipeline (the paper's plain method, optimize=0) and R."""
    radius = radius_for_cells(shape.measure, cells, shape.dim)
    spacing = radius / GRID_PER_RADIUS
    grid = sampled(shape, spacing)
    plain = mesh_from_grid(grid, BitingParameters(radius=radius, seed=seed), optimize=OptimizeParameters(optimize=0))
    return grid, plain.mesh, radius


@pytest.fixture(scope="module")
def optimized():
    """name -> (shape, grid, input mesh, R, optimised mesh, progress messages)."""
    cases = {}
    for name, (shape, cells) in SHAPES.items():
        grid, mesh, radius = meshed(shape, cells)
        messages = []
        result = optimize_mesh(grid, mesh, progress=lambda *report, to=messages: to.append(report))
        cases[name] = (shape, grid, mesh, radius, result, messages)
    return cases


# --- the issue's thresholds ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(SHAPES))
def test_optimized_shapes_are_valid_with_good_cells(optimized, name):
    shape, _, mesh, _, result, _ = optimized[name]
    assert_valid_domain(result, euler=shape.boundary_euler, components=1, mean_quality=0.88)
    q = radius_ratio(result.points, result.cells)
    assert q.min() >= 0.3  # the issue asks >= 0.2
    assert np.nanmin(dihedral_angles(result.points, result.cells)) >= 20.0  # the issue asks >= 15
    assert result.cell_data == {}
    # before: slivers (the paper's section 5)
    assert radius_ratio(mesh.points, mesh.cells).min() < 0.05


@pytest.mark.parametrize("name", list(SHAPES))
def test_the_default_pipeline_gives_these_fem_grade_meshes(optimized, name):
    """Issue 12: FEM-grade is the default.  The pipeline with its default parameters returns exactly the optimised
    mesh judged above (min dihedral >= 20 degrees, no Q < 0.3), with its quality arrays."""
    _, grid, _, radius, result, _ = optimized[name]
    default = mesh_from_grid(grid, BitingParameters(radius=radius, seed=0)).mesh
    assert np.array_equal(default.points, result.points) and np.array_equal(default.cells, result.cells)
    assert default.cell_data["MinDihedralAngle"].min() >= 20.0 and default.cell_data["RadiusRatio"].min() >= 0.3


@pytest.mark.parametrize("name", list(SHAPES))
def test_the_volume_and_the_node_spacing_are_kept(optimized, name):
    shape, _, mesh, _, result, _ = optimized[name]
    assert volume(result) == pytest.approx(volume(mesh), rel=0.01)
    # no farther from the exact volume than the input (the die and the shell gain: notches of the input close)
    assert abs(volume(result) - shape.measure) <= abs(volume(mesh) - shape.measure) + 0.002 * shape.measure
    _, before = edge_lengths(mesh.points, mesh.cells)
    _, after = edge_lengths(result.points, result.cells)
    # the spacing is more even than every peer's in benchmarks/peers.md: the most even there is TetGen -pq1.2a's
    # 0.178 on the sphere (gmsh + Netgen 0.226 and 0.208, unoptimised bitemesh 0.170 and 0.178).  Measured: the
    # shell 0.150 (walls 1.7 edges thick, surface nodes denser than interior ones), the others at most 0.145
    assert after.std() / after.mean() < 0.178
    assert after.std() / after.mean() < before.std() / before.mean() - 0.03
    assert after.mean() == pytest.approx(before.mean(), rel=0.08)
    assert len(result.points) >= 0.97 * len(mesh.points)


@pytest.mark.parametrize("name", list(SHAPES))
def test_boundary_nodes_lie_on_the_surface(optimized, name):
    shape, grid, mesh, radius, result, _ = optimized[name]
    on_boundary = np.unique(boundary_facets(result.cells))
    # on the grid's f = 0, and within 0.05 R of the true surface (|f| is about the distance to it)
    assert np.abs(grid.evaluate(result.points[on_boundary])).max() < 0.01 * radius
    assert np.abs(shape.function(result.points[on_boundary])).max() < 0.05 * radius
    # the input had interior nodes laid bare (the die's and the shell's notches)
    if name in ("die", "two-cavity shell"):
        before = np.unique(boundary_facets(mesh.cells))
        assert np.abs(shape.function(mesh.points[before])).max() > 0.5 * radius


def test_the_sphere_leads_the_peers_of_the_issue(optimized):
    """At about 10,000 cells the issue's peers give mean radius ratio / smallest dihedral angle: gmsh+Netgen
    0.86 / 24 deg, CGAL 0.887 / 15.9 deg (published), TetGen -q 0.82 / 1.4 deg; measured on this sphere in
    benchmarks/peers.md: gmsh+Netgen 0.849 / 23.7 deg with min Q 0.444, TetGen 0.792 / 1.9 deg.  Each bound is the
    best peer's figure, which the optimised sphere must beat (measured: 0.902 / 32.5 deg, min Q 0.586)."""
    _, _, _, _, result, _ = optimized["sphere"]
    q = radius_ratio(result.points, result.cells)
    assert q.mean() > 0.887   # CGAL's published mean, the best of the issue's peers
    assert np.nanmin(dihedral_angles(result.points, result.cells)) > 24.0   # gmsh+Netgen's, the issue's table
    assert q.min() > 0.444   # gmsh+Netgen's smallest radius ratio on the sphere, benchmarks/peers.md


def test_progress_reports_the_convergence_and_what_remains(optimized):
    *_, result, messages = optimized["sphere"]
    fractions = [fraction for fraction, _ in messages]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    relaxation = [message for _, message in messages if message.startswith("relaxation ")]
    means = [float(message.rsplit(" ", 1)[1]) for message in relaxation if "mean radius ratio" in message]
    assert 2 <= len(means) <= OptimizeParameters().iterations and means[-1] > means[0] + 0.02
    # the last message reports the mesh returned (its figure is checked against the peers above, not here)
    last = re.match(r"optimised: mean radius ratio (\d\.\d{4}); ", messages[-1][1])
    assert last, messages[-1][1]
    assert float(last[1]) == pytest.approx(radius_ratio(result.points, result.cells).mean(), abs=5e-5)
    assert "remain 0 cells with an angle below 20 degrees or a radius ratio below 0.3, 0 boundary nodes" in \
        messages[-1][1]


def test_the_thin_walled_heart_meets_the_fem_bounds():
    """The benchmarks' two-cavity heart: its RV free wall (0.10) is about 1.2 R thick at 10,000 cells.  The bounds
    are the optimiser's own (issue 12: min dihedral >= 20 degrees, no Q < 0.3), and the mean radius ratio is at
    least gmsh + Netgen's on this shape (0.837, issue 12's table)."""
    shape = two_cavity_heart()
    box = np.subtract(shape.upper, shape.lower)
    inside = shape.function(shape.lower + np.random.default_rng(0).random((10**6, 3)) * box) > 0
    assert inside.mean() * np.prod(box) == pytest.approx(shape.measure, rel=0.005)   # 1e6 samples: sd 0.1 %
    grid, mesh, _ = meshed(shape, 10000)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BitemeshWarning)
        result = optimize_mesh(grid, mesh)
    assert_valid_domain(result, euler=2, components=1, mean_quality=0.837)
    assert radius_ratio(result.points, result.cells).min() >= 0.3
    assert np.nanmin(dihedral_angles(result.points, result.cells)) >= 20.0


def test_bounds_it_cannot_meet_are_a_warning_with_the_figures():
    """No tetrahedron of a uniform mesh has every dihedral angle at 59 degrees (the regular one has 70.5 and then
    others are smaller): the optimiser returns its best mesh and says by how much it missed."""
    grid, mesh, _ = meshed(sphere(), 2000)
    with pytest.warns(BitemeshWarning, match=r"could not meet its bounds: \d+ of \d+ cells remain below "
                      r"min_dihedral = 59 degrees .*smallest angle \d+\.\d degrees.*lower radius"):
        result = optimize_mesh(grid, mesh, OptimizeParameters(min_dihedral=59.0))
    assert_valid_domain(result, euler=2, components=1)


def test_bounds_it_meets_give_no_warning(optimized):
    grid, mesh = optimized["sphere"][1], optimized["sphere"][2]
    with warnings.catch_warnings():
        warnings.simplefilter("error", BitemeshWarning)
        optimize_mesh(grid, mesh, OptimizeParameters(iterations=5))


def test_a_2d_mesh_gets_angles_of_at_least_25_degrees():
    shape = annulus()
    grid, mesh, radius = meshed(shape, 1000)
    result = optimize_mesh(grid, mesh)
    assert result.cells.shape[1] == 3
    assert_valid_domain(result, measure=shape.measure, measure_tolerance=0.01, mean_quality=0.95)
    assert np.nanmin(dihedral_angles(result.points, result.cells)) >= 25.0
    assert volume(result) == pytest.approx(volume(mesh), rel=0.001)
    on_boundary = np.unique(boundary_facets(result.cells))
    assert np.abs(shape.function(result.points[on_boundary])).max() < 0.05 * radius


def test_a_second_pass_keeps_an_optimized_mesh_valid_and_as_good(optimized):
    shape, grid, _, _, first, _ = optimized["two-cavity shell"]
    second = optimize_mesh(grid, first)
    assert_valid_domain(second, euler=shape.boundary_euler, components=1)
    assert radius_ratio(second.points, second.cells).mean() >= radius_ratio(first.points, first.cells).mean() - 1e-9
    assert np.nanmin(dihedral_angles(second.points, second.cells)) >= 20.0
    assert volume(second) == pytest.approx(volume(first), rel=0.005)


# --- behaviour of the step -----------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small():
    """A sphere of about 3,000 cells: grid, mesh, R."""
    return meshed(sphere(), 3000)


def test_same_input_same_output_and_the_input_is_not_modified(small):
    grid, mesh, _ = small
    points, cells, names = mesh.points.copy(), mesh.cells.copy(), set(mesh.cell_data)
    first = optimize_mesh(grid, mesh)
    again = optimize_mesh(grid, mesh)
    assert np.array_equal(first.points, again.points) and np.array_equal(first.cells, again.cells)
    assert np.array_equal(mesh.points, points) and np.array_equal(mesh.cells, cells)
    assert {"RadiusRatio", "MinDihedralAngle", "MaxDihedralAngle", "Volume"} <= set(mesh.cell_data) == names


def test_without_relaxation_flips_and_smoothing_alone_remove_the_slivers(small):
    grid, mesh, _ = small
    result = optimize_mesh(grid, mesh, OptimizeParameters(iterations=0))
    assert_valid_domain(result, euler=2, components=1)
    assert len(result.points) == len(mesh.points)  # no node dropped: the nodes only moved
    assert np.nanmin(dihedral_angles(result.points, result.cells)) >= 20.0
    assert radius_ratio(result.points, result.cells).mean() > radius_ratio(mesh.points, mesh.cells).mean() + 0.01


def test_cancelling_stops_the_step(small):
    grid, mesh, _ = small

    def cancel(fraction, message):
        if message.startswith("flip pass"):
            raise Cancelled("stop")
    with pytest.raises(Cancelled):
        optimize_mesh(grid, mesh, progress=cancel)


def test_when_nothing_valid_comes_out_the_input_comes_back(small, monkeypatch):
    grid, mesh, _ = small

    def broken(grid, points, cells, *args):  # an inverted cell in every state of the sliver removal
        return [(points, np.concatenate([cells[1:], cells[:1, [1, 0, 2, 3]]]))]

    def failing(*args, **kwargs):
        raise MeshingError("the relaxed nodes leave no cell inside the domain")
    monkeypatch.setattr(optimizer, "remove_slivers", broken)
    monkeypatch.setattr(optimizer, "relax", failing)
    result = optimize_mesh(grid, mesh)
    assert np.array_equal(result.points, mesh.points) and np.array_equal(result.cells, mesh.cells)
    assert result.cell_data == {}
    invalid = Mesh(mesh.points, np.concatenate([mesh.cells, mesh.cells[:1]]))
    with pytest.raises(MeshingError, match="not a valid domain"):
        optimize_mesh(grid, invalid)


def test_a_relaxation_that_changes_the_topology_is_abandoned(small, monkeypatch):
    grid, mesh, _ = small
    interior = np.flatnonzero(~np.isin(mesh.cells, boundary_facets(mesh.cells)).any(axis=1))

    def with_a_void(grid, points, cells, *args, **kwargs):  # valid, but one interior cell gone: a second boundary
        return points, np.delete(cells, interior[0], axis=0), []
    monkeypatch.setattr(optimizer, "relax", with_a_void)
    messages = []
    result = optimize_mesh(grid, mesh, progress=lambda *report: messages.append(report[1]))
    assert any("relaxation abandoned" in message and "Euler" in message for message in messages)
    assert_valid_domain(result, euler=2, components=1)
    assert np.nanmin(dihedral_angles(result.points, result.cells)) >= 20.0


def test_wrong_inputs_are_refused_with_a_message(small):
    grid, mesh, _ = small
    flat = Mesh(mesh.points[:, :2], mesh.cells[:, :3])
    with pytest.raises(InvalidInputError, match="mesh is 2D but grid is 3D"):
        optimize_mesh(grid, flat)
    with pytest.raises(InvalidInputError, match="no cells"):
        optimize_mesh(grid, Mesh(mesh.points, np.zeros((0, 4), np.int64)))
    with pytest.raises(InvalidInputError, match="iterations"):
        OptimizeParameters(iterations=-1)
    with pytest.raises(InvalidInputError, match="min_dihedral"):
        OptimizeParameters(min_dihedral=60)
    with pytest.raises(InvalidInputError, match="min_quality"):
        OptimizeParameters(min_quality=1.5)


def test_relaxation_raises_the_mean_quality_and_keeps_the_boundary_facets(small):
    grid, mesh, _ = small
    points, cells, history = relax(grid, mesh.points, mesh.cells, 30)
    assert check_valid_domain(Mesh(points, cells)) == []
    assert np.array_equal(unique_rows(boundary_facets(cells))[0], unique_rows(boundary_facets(mesh.cells))[0])
    assert 3 <= len(history) < 30  # it converged before the bound
    assert history[-1] > radius_ratio(mesh.points, mesh.cells).mean() + 0.05


@pytest.mark.parametrize("spread", [0.3, 1.0])
def test_moves_that_would_flatten_a_cell_go_back_and_the_others_stay(small, spread):
    """Random moves of ``spread`` x R: each node ends at its target or where it was, no cell flat."""
    grid, mesh, radius = small
    targets = mesh.points + np.random.default_rng(0).normal(scale=spread * radius, size=mesh.points.shape)
    moved = relaxation.positive_moves(mesh.points, targets, mesh.cells)
    kept = np.all(moved == targets, axis=1)
    assert (kept | np.all(moved == mesh.points, axis=1)).all() and kept.any()
    assert radius_ratio(moved, mesh.cells).min() > relaxation.FLAT_QUALITY


def test_flips_keep_the_boundary_the_nodes_and_the_volume(small):
    _, mesh, _ = small
    cells = flip(mesh.points, mesh.cells)
    assert check_valid_domain(Mesh(mesh.points, cells)) == []
    assert np.array_equal(unique_rows(boundary_facets(cells))[0], unique_rows(boundary_facets(mesh.cells))[0])
    assert signed_measures(mesh.points, cells).sum() == pytest.approx(volume(mesh), rel=1e-12)
    assert radius_ratio(mesh.points, cells).min() > 4 * radius_ratio(mesh.points, mesh.cells).min()


@pytest.mark.parametrize("revert_rounds", [relaxation.REVERT_ROUNDS, 1])
def test_smoothing_keeps_cells_positive_and_boundary_nodes_on_f_zero(small, revert_rounds, monkeypatch):
    """With one revert round, every node still worse after it is a chain: its neighbours' moves go back with it
    and the other nodes keep theirs (before 027e61a the whole iteration went back: no node moved)."""
    monkeypatch.setattr(relaxation, "REVERT_ROUNDS", revert_rounds)
    grid, mesh, radius = small
    points = smooth(grid, mesh.points, mesh.cells, 5)
    assert (signed_measures(points, mesh.cells) > 0).all()
    on_boundary = np.unique(boundary_facets(mesh.cells))
    assert np.abs(grid.evaluate(points[on_boundary])).max() < 0.01 * radius
    before = (inverse_mean_ratio(mesh.points, mesh.cells) ** 2).sum()
    assert (inverse_mean_ratio(points, mesh.cells) ** 2).sum() < 0.95 * before
