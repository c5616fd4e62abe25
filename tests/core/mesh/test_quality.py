"""Quality measures and validity checks of bitemesh.core.mesh.quality, on tiny hand-made meshes (no VTK)."""
import re
from itertools import permutations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from bitemesh.core.errors import InvalidInputError
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain, count_boundary_components
from bitemesh.core.mesh.topology import boundary_facets, connected_components
from bitemesh.core.mesh.quality import (cell_quality, dihedral_angles, edge_lengths, format_summary, quality_histogram,
                                   quality_summary, radius_ratio)

from tests.builders import positively_oriented

REGULAR_DIHEDRAL = np.degrees(np.arccos(1 / 3))  # 70.5288 deg
ONE_TET = np.array([[0, 1, 2, 3]])
ONE_TRIANGLE = np.array([[0, 1, 2]])


def regular_tet():
    points = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    return points, positively_oriented(points, ONE_TET)


def corner_tet():
    return np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float), ONE_TET.copy()


def sliver(height=1e-3):
    """Four corners of the unit square, two opposite ones lifted by ``height``."""
    points = np.array([[0, 0, 0], [1, 1, 0], [1, 0, height], [0, 1, height]])
    return points, positively_oriented(points, ONE_TET)


def unit_cube():
    """The unit cube split into the 6 tetrahedra of the Kuhn triangulation (all around the diagonal 0-7)."""
    points = np.array([[(i >> a) & 1 for a in range(3)] for i in range(8)], dtype=float)
    cells = [[0, 1 << a, (1 << a) | (1 << b), 7] for a, b, _ in permutations(range(3))]
    return Mesh(points, positively_oriented(points, cells))


def annulus(n=16, inner=1.0, outer=2.0):
    """A ring of 2 n triangles between two concentric regular n-gons."""
    angle = 2 * np.pi * np.arange(n) / n
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    points = np.concatenate([inner * circle, outer * circle])
    i, j = np.arange(n), (np.arange(n) + 1) % n
    cells = np.concatenate([np.stack([i, n + i, n + j], 1), np.stack([i, n + j, j], 1)])
    return Mesh(points, positively_oriented(points, cells))


def tets_at(corner_sets):
    """A mesh of separate tetrahedra (no shared points), one per (4, 3) array of corners."""
    points = np.concatenate(corner_sets).astype(float)
    return Mesh(points, positively_oriented(points, np.arange(len(points)).reshape(-1, 4)))


def random_similarity(rng, dim):
    rotation, upper = np.linalg.qr(rng.normal(size=(dim, dim)))
    rotation *= np.sign(np.diag(upper))  # uniform over O(dim), reflections included
    return 10.0 ** rng.uniform(-3, 3) * rotation, rng.uniform(-100, 100, dim)


# --- radius ratio and angles ---------------------------------------------------------------------------------


def test_regular_tet_has_unit_quality_and_equal_dihedral_angles():
    points, cells = regular_tet()
    assert radius_ratio(points, cells) == pytest.approx([1.0], abs=1e-12)
    assert dihedral_angles(points, cells) == pytest.approx(np.full((1, 6), REGULAR_DIHEDRAL), abs=1e-10)


def test_corner_tet_pins_quality_and_dihedral_order():
    points, cells = corner_tet()
    assert radius_ratio(points, cells) == pytest.approx([np.sqrt(3) - 1], rel=1e-12)
    # edges (0,1), (0,2), (0,3) meet at right angles; (1,2), (1,3), (2,3) at arctan(sqrt 2)
    expected = [90, 90, 90] + [np.degrees(np.arctan(np.sqrt(2)))] * 3
    assert dihedral_angles(points, cells) == pytest.approx(np.array([expected]), abs=1e-10)


def test_equilateral_triangle_has_unit_quality_and_60_degree_angles():
    points = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]])
    assert radius_ratio(points, ONE_TRIANGLE) == pytest.approx([1.0], abs=1e-12)
    assert dihedral_angles(points, ONE_TRIANGLE) == pytest.approx(np.full((1, 3), 60.0), abs=1e-10)


def test_triangle_angles_are_at_vertices_in_order():
    points = np.array([[0, 0], [2, 0], [0, 1]])
    expected = [90, np.degrees(np.arctan(0.5)), np.degrees(np.arctan(2))]
    assert dihedral_angles(points, ONE_TRIANGLE) == pytest.approx(np.array([expected]), abs=1e-10)


def test_sliver_has_quality_near_zero_and_dihedral_angles_near_0_and_180():
    points, cells = sliver(1e-3)
    assert 0 < radius_ratio(points, cells)[0] < 1e-2
    angles = np.sort(dihedral_angles(points, cells)[0])
    assert angles[:4] == pytest.approx(np.zeros(4), abs=0.2)
    assert angles[4:] == pytest.approx([180, 180], abs=0.2)


def test_dihedral_angles_match_an_independent_construction():
    """At edge (a, b): the angle between c and d projected on the plane normal to the edge."""
    rng = np.random.default_rng(7)
    points = rng.normal(size=(40, 3))
    cells = np.arange(40).reshape(10, 4)
    corners = points[cells]
    expected = []
    for a, b in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]:
        c, d = (j for j in range(4) if j not in (a, b))
        axis = corners[:, b] - corners[:, a]
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        u, v = corners[:, c] - corners[:, a], corners[:, d] - corners[:, a]
        u -= np.einsum("ij,ij->i", u, axis)[:, None] * axis
        v -= np.einsum("ij,ij->i", v, axis)[:, None] * axis
        cosine = np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
        expected.append(np.degrees(np.arccos(cosine)))
    assert dihedral_angles(points, cells) == pytest.approx(np.stack(expected, axis=1), abs=1e-7)


def test_flat_and_collapsed_cells_have_zero_quality():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)  # coplanar
    assert radius_ratio(points, ONE_TET) == [0.0]
    points[3] = points[0]  # a repeated vertex: the angles at the collapsed facets are undefined
    assert radius_ratio(points, ONE_TET) == [0.0]
    assert np.isnan(dihedral_angles(points, ONE_TET)).any()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dim=st.sampled_from([2, 3]))
def test_quality_and_angles_are_invariant_under_similarities(seed, dim):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(dim + 1, dim))
    cells = np.arange(dim + 1)[None]
    q = radius_ratio(points, cells)
    if q[0] < 0.05:  # too ill-conditioned to compare to 1e-8
        return
    scale_rotation, shift = random_similarity(rng, dim)
    moved = points @ scale_rotation.T + shift
    assert radius_ratio(moved, cells) == pytest.approx(q, rel=1e-8)
    assert dihedral_angles(moved, cells) == pytest.approx(dihedral_angles(points, cells), abs=1e-6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dim=st.sampled_from([2, 3]))
def test_quality_is_in_unit_interval_even_for_degenerate_cells(seed, dim):
    rng = np.random.default_rng(seed)
    points = rng.integers(0, 3, size=(12, dim)).astype(float)  # many coplanar and repeated points
    cells = np.array([rng.permutation(12)[: dim + 1] for _ in range(50)])
    q = radius_ratio(points, cells)
    assert np.all((q >= 0) & (q <= 1))
    assert np.all(q[np.abs(signed_measures(points, cells)) == 0] == 0)


def test_triangle_angles_sum_to_180():
    points = np.random.default_rng(1).normal(size=(30, 2))
    cells = np.arange(30).reshape(10, 3)
    assert dihedral_angles(points, cells).sum(axis=1) == pytest.approx(np.full(10, 180.0), abs=1e-9)


def test_edge_lengths_of_the_cube():
    edges, lengths = edge_lengths(unit_cube().points, unit_cube().cells)
    assert len(edges) == 19  # 12 sides, 6 face diagonals, 1 body diagonal
    assert np.all(edges[:, 0] < edges[:, 1]) and len(np.unique(edges, axis=0)) == 19
    assert np.sort(lengths) == pytest.approx([1] * 12 + [np.sqrt(2)] * 6 + [np.sqrt(3)])


def test_cell_quality_arrays():
    points, cells = regular_tet()
    arrays = cell_quality(Mesh(points, cells))
    assert set(arrays) == {"RadiusRatio", "MinDihedralAngle", "MaxDihedralAngle", "Volume"}
    assert arrays["Volume"] == pytest.approx([8 / 3])
    assert arrays["MinDihedralAngle"] == pytest.approx([REGULAR_DIHEDRAL])
    assert arrays["MaxDihedralAngle"] == pytest.approx([REGULAR_DIHEDRAL])
    area = cell_quality(Mesh(np.array([[0, 0], [2, 0], [0, 1.0]]), ONE_TRIANGLE))
    assert area["Volume"] == pytest.approx([1.0])
    assert area["MinDihedralAngle"] == pytest.approx([np.degrees(np.arctan(0.5))])
    assert area["MaxDihedralAngle"] == pytest.approx([90.0])


# --- summary and histogram -----------------------------------------------------------------------------------


def hand_made_mix():
    """Five separate tetrahedra: regular tets squashed along z, with Q about 1, 0.57, 0.25, 0.15 and 0.04."""
    regular, _ = regular_tet()
    return tets_at([regular * [1, 1, s] for s in (1.0, 0.3, 0.12, 0.07, 0.02)])


def test_summary_on_a_hand_made_mix():
    mesh = hand_made_mix()
    q = radius_ratio(mesh.points, mesh.cells)
    assert [q[0] > 0.99, 0.5 < q[1] < 0.6, 0.2 < q[2] < 0.3, 0.1 < q[3] < 0.2, q[4] < 0.1] == [True] * 5
    summary = quality_summary(mesh)
    assert (summary.dim, summary.n_cells, summary.n_points) == (3, 5, 20)
    assert (summary.percent_q_below_0_1, summary.percent_q_below_0_2, summary.percent_q_below_0_3) == \
        pytest.approx((20.0, 40.0, 60.0))
    assert summary.q_mean == pytest.approx(q.mean())
    assert summary.q_std == pytest.approx(q.std())
    assert summary.q_min == pytest.approx(q[4])
    assert summary.q_p50 == pytest.approx(q[2])
    assert summary.q_p1 < summary.q_p5 < summary.q_p50
    assert summary.angle_max == pytest.approx(dihedral_angles(mesh.points, mesh.cells).max())
    assert summary.angle_min == pytest.approx(dihedral_angles(mesh.points, mesh.cells).min())
    assert summary.total_volume == pytest.approx(8 / 3 * (1 + 0.3 + 0.12 + 0.07 + 0.02))
    _, lengths = edge_lengths(mesh.points, mesh.cells)
    assert len(lengths) == 30
    assert (summary.edge_mean, summary.edge_std, summary.edge_min, summary.edge_max) == \
        pytest.approx((lengths.mean(), lengths.std(), lengths.min(), lengths.max()))
    assert summary.edge_cv == pytest.approx(lengths.std() / lengths.mean())


def test_format_summary_is_an_aligned_block():
    text = format_summary(quality_summary(hand_made_mix()))
    lines = text.splitlines()
    assert str(quality_summary(hand_made_mix())) == text
    assert "5 tetrahedra, 20 points" in lines[0] and "dihedral angle" in text
    assert len({re.match(r"\S.*?\s{2,}(?=\S)", line).end() for line in lines}) == 1  # values in one column
    assert "triangles" in format_summary(quality_summary(annulus())) and "interior angle" in \
        format_summary(quality_summary(annulus()))


def test_summary_of_an_empty_mesh_is_refused():
    with pytest.raises(InvalidInputError, match="no cells"):
        quality_summary(Mesh(np.zeros((4, 3)), np.zeros((0, 4), dtype=np.int64)))


def test_histogram_covers_the_unit_interval():
    counts, edges = quality_histogram(np.array([0.0, 0.05, 0.5, 0.97, 1.0]), bins=10)
    assert edges == pytest.approx(np.linspace(0, 1, 11))
    assert counts.tolist() == [2, 0, 0, 0, 0, 1, 0, 0, 0, 2]
    with pytest.raises(InvalidInputError, match="bins"):
        quality_histogram(np.zeros(3), bins=2.5)
    with pytest.raises(InvalidInputError, match="bins"):
        quality_histogram(np.zeros(3), bins=0)


# --- topology and validity ----------------------------------------------------------------------------------


def test_cube_is_a_valid_domain_with_a_sphere_like_boundary():
    cube = unit_cube()
    assert signed_measures(cube.points, cube.cells).sum() == pytest.approx(1.0)
    assert check_valid_domain(cube) == []
    assert boundary_euler_characteristic(cube) == 2
    assert count_boundary_components(cube) == 1
    assert connected_components(cube.cells).tolist() == [0] * 6
    assert len(boundary_facets(cube.cells)) == 12


def test_boundary_facets_point_outward():
    cube = unit_cube()
    triangles = cube.points[boundary_facets(cube.cells)]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert np.all(np.einsum("ij,ij->i", normals, triangles.mean(axis=1) - 0.5) > 0)
    ring = annulus()
    edges = ring.points[boundary_facets(ring.cells)]
    # with the domain on the left of every edge, the shoelace sum over the boundary is the area
    shoelace = 0.5 * np.sum(edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 1, 0] * edges[:, 0, 1])
    assert shoelace == pytest.approx(signed_measures(ring.points, ring.cells).sum())


def test_annulus_is_valid_with_two_boundary_loops():
    ring = annulus(16)
    assert check_valid_domain(ring) == []
    assert count_boundary_components(ring) == 2
    assert boundary_euler_characteristic(ring) == 0
    assert len(boundary_facets(ring.cells)) == 32
    assert signed_measures(ring.points, ring.cells).sum() == pytest.approx(8 * np.sin(np.pi / 8) * 3)


def test_two_tets_sharing_only_an_edge_have_a_non_manifold_boundary():
    corner, _ = corner_tet()
    mesh = tets_at([corner, corner * [-1, -1, 1]])
    mesh = Mesh(mesh.points[[0, 1, 2, 3, 5, 6]], np.array([[0, 1, 2, 3], [0, 4, 5, 3]]))
    mesh = Mesh(mesh.points, positively_oriented(mesh.points, mesh.cells))
    problems = check_valid_domain(mesh)
    assert len(problems) == 1 and "boundary edges not in exactly two boundary triangles" in problems[0]
    assert "edge (0, 3) in 4" in problems[0]
    assert connected_components(mesh.cells).tolist() == [0, 1]


def test_two_tets_sharing_only_a_vertex_have_a_non_manifold_boundary():
    corner, _ = corner_tet()
    points = np.concatenate([corner, -corner[1:]])
    mesh = Mesh(points, positively_oriented(points, [[0, 1, 2, 3], [0, 4, 5, 6]]))
    problems = check_valid_domain(mesh)
    assert len(problems) == 1 and "more than one fan" in problems[0] and "point 0 with 2 fans" in problems[0]
    assert count_boundary_components(mesh) == 1
    assert boundary_euler_characteristic(mesh) == 3  # 7 - 12 + 8


def test_two_triangles_sharing_only_a_vertex_have_a_non_manifold_boundary():
    points = np.array([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]], dtype=float)
    mesh = Mesh(points, positively_oriented(points, [[0, 1, 2], [0, 3, 4]]))
    problems = check_valid_domain(mesh)
    assert len(problems) == 1 and "point 0 in 4" in problems[0]


def test_flipped_tet_is_detected():
    points, cells = corner_tet()
    problems = check_valid_domain(Mesh(points, cells[:, [1, 0, 2, 3]]))
    assert len(problems) == 1 and "inverted" in problems[0]
    cube = unit_cube()
    cells = cube.cells.copy()
    cells[2, :2] = cells[2, 1::-1]
    problems = check_valid_domain(Mesh(cube.points, cells))
    assert any("inverted" in p and "cell 2" in p for p in problems)
    assert any("same side" in p for p in problems)


def test_flat_tet_is_detected_with_a_relative_tolerance():
    points, cells = sliver(1e-14)
    assert any("flat cells" in p for p in check_valid_domain(Mesh(points * 1e-6, cells)))
    assert check_valid_domain(Mesh(points * 1e-6, cells), volume_rtol=0) == []
    points, cells = sliver(1e-6)
    assert check_valid_domain(Mesh(points * 1e-6, cells)) == []


def test_duplicate_cells_and_overfull_facets_are_detected():
    cube = unit_cube()
    problems = check_valid_domain(Mesh(cube.points, np.concatenate([cube.cells, cube.cells[:1]])))
    assert any(p.startswith("2 cells with the same vertices") for p in problems)
    assert any("facets shared by more than two cells" in p for p in problems)


def test_three_tets_on_one_triangle_are_detected():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0.2, 0.2, 2]], dtype=float)
    mesh = Mesh(points, positively_oriented(points, [[0, 1, 2, 3], [0, 1, 2, 4], [0, 1, 2, 5]]))
    problems = check_valid_domain(mesh)
    assert any(p.startswith("1 facets shared by more than two cells (first: facet (0, 1, 2) in 3") for p in problems)


def test_unused_and_non_finite_points_are_detected():
    cube = unit_cube()
    points = np.concatenate([cube.points, [[5, 5, 5], [np.nan, 0, 0]]])
    problems = check_valid_domain(Mesh(points, cube.cells))
    assert problems == ["1 points with NaN or infinite coordinates (first: point 9)",
                        "2 points used by no cell (first: point 8)"]


def test_malformed_meshes_are_refused_naming_the_array():
    cube = unit_cube()
    with pytest.raises(InvalidInputError, match="mesh.cells refers to vertex 7 but there are only 7 points"):
        check_valid_domain(Mesh(cube.points[:7], cube.cells))
    with pytest.raises(InvalidInputError, match="mesh.cells must have 4 vertices"):
        cell_quality(Mesh(cube.points, cube.cells[:, :3]))
    with pytest.raises(InvalidInputError, match="integer"):
        cell_quality(Mesh(cube.points, cube.cells.astype(float)))


def test_connected_components_through_facets_only():
    cube = unit_cube()
    points = np.concatenate([cube.points, cube.points + [3, 0, 0]])
    cells = np.concatenate([cube.cells, cube.cells + 8])
    assert connected_components(cells).tolist() == [0] * 6 + [1] * 6
    mesh = Mesh(points, cells)
    assert count_boundary_components(mesh) == 2 and boundary_euler_characteristic(mesh) == 4


def test_huge_vertex_indices_give_the_same_topology():
    """Above about 2 million points the int64 keys of triangles overflow; the row-wise path must agree."""
    cells = unit_cube().cells
    big = 3_000_000
    assert np.array_equal(boundary_facets(cells + big), boundary_facets(cells) + big)
    assert connected_components(np.concatenate([cells, cells + big])).tolist() == [0] * 6 + [1] * 6


def test_a_large_kuhn_block_is_valid():
    """A Kuhn-triangulated 24^3 block: 82944 tets, one component, a sphere-like boundary, volume n^3."""
    n = 24
    grid = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    index = np.arange((n + 1) ** 3).reshape((n + 1,) * 3)
    corner = index[:-1, :-1, :-1].ravel()
    offset = np.array([1 << a for a in range(3)])
    step = {0: 0}
    for bits in range(1, 8):
        step[bits] = sum(((bits >> a) & 1) * (n + 1) ** (2 - a) for a in range(3))
    cells = np.concatenate([
        np.stack([corner, corner + step[offset[a]], corner + step[offset[a] | offset[b]], corner + step[7]], 1)
        for a, b, _ in permutations(range(3))])
    mesh = Mesh(grid, positively_oriented(grid, cells))
    problems = check_valid_domain(mesh)
    euler = boundary_euler_characteristic(mesh)
    labels = connected_components(mesh.cells)
    assert (problems, euler, labels.max()) == ([], 2, 0)
    assert signed_measures(mesh.points, mesh.cells).sum() == pytest.approx(n ** 3)

