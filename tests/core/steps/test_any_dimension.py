"""The method in 4-D and 5-D (issue 36): the grid I of the function, the biting, qhull's Delaunay, the spurious-cell
rule and the validity check of the 2-D and 3-D path, on balls and a solid torus with known measure and topology; and
the sections of such meshes (an instant of a space-time mesh)."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from bitemesh.core.grid.sampled import FunctionGrid, sample_function
from bitemesh.core.mesh.quality import radius_ratio
from bitemesh.core.mesh.simplicial import circumspheres, signed_measures
from bitemesh.core.mesh.slicing import slice_mesh
from bitemesh.core.mesh.topology import boundary_facets, euler_characteristic
from bitemesh.core.mesh.validity import (boundary_euler_characteristic, check_valid_domain,
                                         count_boundary_components)
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid

from tests.meshcheck import BALL, largest_facet_circumradius


def ball(x):
    return 1.0 - np.linalg.norm(x, axis=1)


def solid_torus(x):
    """S^1 x B^3 in 4-D: the points within 0.4 of the unit circle in the (x0, x1) plane."""
    ring = np.hypot(x[:, 0], x[:, 1]) - 1.0
    return 0.4 - np.sqrt(ring**2 + np.sum(x[:, 2:] ** 2, axis=1))


@lru_cache(maxsize=None)
def meshed(shape: str, k: int, radius: float, seed: int = 0, optimize: int = 1):
    """The default relaxes beyond 3-D; 5-D for at most three iterations (4 to 8 s each here)."""
    function, reach = (ball, 1.0) if shape == "ball" else (solid_torus, 1.4)
    lower = -np.full(k, reach)
    if shape == "torus":
        lower[2:] = -0.4
    grid = sample_function(function, lower, -lower, radius / 4, margin=radius / 2)
    parameters = OptimizeParameters(optimize=optimize, iterations=3 if k == 5 else 30)
    return grid, mesh_from_grid(grid, BitingParameters(radius=radius, seed=seed), optimize=parameters)


@pytest.mark.parametrize("k, radius", [(4, 0.3), (5, 0.45)])
def test_the_k_ball_is_a_valid_domain_inscribed_in_it(k, radius):
    """The 4-ball and the 5-ball: a valid domain (no zero-volume cell) on a grid that keeps no f, one boundary, an
    S^(k-1) (Euler characteristic 0, 2), the domain a ball (1); the mesh is the hull of its nodes, every node in the
    ball and the boundary nodes on its sphere, so its measure lies between the ball's and that of the ball of radius
    sqrt(1 - r^2) that the hull's facets (circumradius at most r) leave inside."""
    grid, result = meshed("ball", k, radius)
    mesh = result.mesh
    assert isinstance(grid, FunctionGrid)
    assert check_valid_domain(mesh) == []
    assert (signed_measures(mesh.points, mesh.cells) > 0).all()
    assert count_boundary_components(mesh) == 1
    assert boundary_euler_characteristic(mesh) == 1 + (-1) ** (k - 1)
    assert euler_characteristic(mesh.cells) == 1
    volume = signed_measures(mesh.points, mesh.cells).sum()
    assert volume == pytest.approx(ConvexHull(mesh.points).volume, rel=1e-9)
    assert np.linalg.norm(mesh.points, axis=1).max() <= 1.0 + 1e-6
    facets = boundary_facets(mesh.cells)
    assert np.allclose(np.linalg.norm(mesh.points[np.unique(facets)], axis=1), 1.0, atol=1e-4)
    facet_radius = largest_facet_circumradius(mesh.points[facets])
    assert BALL[k] * (1 - facet_radius**2) ** (k / 2) <= volume <= BALL[k]


@pytest.mark.parametrize("seed", [0, 1])
def test_a_4d_shell_one_cell_thick_is_a_valid_domain_between_its_spheres(seed):
    """The shell 0.6 <= |x| <= 1 in 4-D at R = 0.4, its wall one R thick (as a heart's walls are in space-time):
    its Delaunay domain was pinched at boundary vertices (their boundary tetrahedra two stars) that the repair did
    not see, refused; now valid, bounded by two 3-spheres (Euler characteristic 0 each), its measure between that of
    the outer polytope's inner ball less the inner ball, and the outer ball less the inner polytope's inner ball
    (facets of circumradius rho inscribed in a sphere of radius a hold the ball of radius sqrt(a^2 - rho^2))."""
    radius = 0.4
    grid = sample_function(lambda x: 0.2 - np.abs(np.linalg.norm(x, axis=1) - 0.8), -np.ones(4), np.ones(4),
                           radius / 4, margin=radius / 2)
    mesh = mesh_from_grid(grid, BitingParameters(radius=radius, seed=seed), optimize=OptimizeParameters()).mesh
    assert check_valid_domain(mesh) == []
    assert count_boundary_components(mesh) == 2 and boundary_euler_characteristic(mesh) == 0
    rho = largest_facet_circumradius(mesh.points[boundary_facets(mesh.cells)])
    volume = signed_measures(mesh.points, mesh.cells).sum()
    assert BALL[4] * ((1 - rho**2) ** 2 - 0.6**4) <= volume <= BALL[4] * (1 - max(0.36 - rho**2, 0) ** 2)


def test_a_solid_torus_in_4d_has_the_topology_of_a_circle():
    """S^1 x B^3: valid, one boundary (S^1 x S^2, Euler characteristic 0), the domain's Euler characteristic that
    of a circle (0; a ball's is 1), and its measure at most 2 pi x (4/3) pi r^3 (r = 0.4: the nodes lie in it) and
    at least that of the tube of radius sqrt(r^2 - R^2) that facets about R wide leave inside."""
    _, result = meshed("torus", 4, 0.2)
    mesh = result.mesh
    assert check_valid_domain(mesh) == []
    assert count_boundary_components(mesh) == 1 and boundary_euler_characteristic(mesh) == 0
    assert euler_characteristic(mesh.cells) == 0
    exact = 2 * np.pi * 4 / 3 * np.pi * 0.4**3
    assert exact * (1 - (0.2 / 0.4) ** 2) ** 1.5 <= signed_measures(mesh.points, mesh.cells).sum() <= exact


@pytest.mark.parametrize("k", [4, 5])
def test_the_relaxation_beyond_3d_raises_the_radius_ratio_to_the_3d_method_s(k):
    """The relaxation by new triangulations (ODT moves, qhull, the carve) on the k-ball: valid, no cell without
    volume, the mean radius ratio above the plain method's; in 4-D at least that of the plain method in 3-D (the
    3-ball at the same R) less 0.1 (the issue's target; the regular k-simplex is 1 in every k; in 5-D, three
    iterations here, 0.67 against 0.61 plain)."""
    radius = {4: 0.3, 5: 0.45}[k]
    _, relaxed = meshed("ball", k, radius)
    _, plain = meshed("ball", k, radius, optimize=0)
    _, three = meshed("ball", 3, radius, optimize=0)
    quality = {name: radius_ratio(m.mesh.points, m.mesh.cells) for name, m in
               (("relaxed", relaxed), ("plain", plain), ("3-D", three))}
    assert check_valid_domain(relaxed.mesh) == []
    assert quality["relaxed"].mean() > quality["plain"].mean()
    assert k == 5 or quality["relaxed"].mean() >= quality["3-D"].mean() - 0.1
    assert (signed_measures(relaxed.mesh.points, relaxed.mesh.cells) > 0).all()


def test_the_same_seed_gives_the_same_k_d_mesh_and_another_seed_another():
    """Deterministic: the 4-ball meshed (and relaxed) twice with seed 0 is the same bit for bit; seed 1 moves the
    nodes."""
    _, first = meshed("ball", 4, 0.3)
    grid = sample_function(ball, -np.ones(4), np.ones(4), 0.075, margin=0.15)
    again = mesh_from_grid(grid, BitingParameters(radius=0.3), optimize=OptimizeParameters()).mesh
    assert np.array_equal(again.points, first.mesh.points) and np.array_equal(again.cells, first.mesh.cells)
    _, other = meshed("ball", 4, 0.3, seed=1)
    assert not np.array_equal(other.mesh.points[:10], first.mesh.points[:10])


def test_the_grid_of_a_function_evaluates_and_projects_as_a_sampled_one():
    """FunctionGrid: f itself at nodes and points, its gradient the unit radial direction of the ball's distance to
    1e-6, and points a spacing off projected onto f = 0 to within a thousandth of a spacing."""
    grid = sample_function(ball, -np.ones(4), np.ones(4), 0.1)
    points = np.random.default_rng(0).normal(size=(50, 4))
    points *= np.linspace(0.9, 1.1, 50)[:, None] / np.linalg.norm(points, axis=1, keepdims=True)   # a spacing off
    assert np.allclose(grid.evaluate(points), ball(points))
    assert np.allclose(grid.gradient(points), -points / np.linalg.norm(points, axis=1, keepdims=True), atol=1e-6)
    assert np.abs(ball(grid.project(points))).max() < 1e-4
    assert grid.inside().shape == grid.shape and grid.node_values(np.array([0]))[0] == ball(grid.origin[None])[0]
    centres, _ = circumspheres(points[:5], np.arange(5)[None])
    assert np.isfinite(grid.evaluate(centres)).all()


def test_a_section_of_the_4_ball_is_a_valid_3_ball_and_the_sections_add_up_to_it():
    """slice_mesh: the 4-ball's mesh cut at x3 = 0.05 is a valid conforming 3-D mesh (one boundary, Euler
    characteristic 2), inside the section's ball; cut through a node and 1e-12 beside it, still valid; and the
    measures of 201 sections integrate (trapezoids, Cavalieri) to the 4-D measure within 1e-3 (the sections'
    measure is piecewise cubic in the cut: the rule's error at that step, 0.01, is about 1e-4)."""
    _, result = meshed("ball", 4, 0.3)
    mesh = result.mesh
    section = slice_mesh(mesh, 0.05)
    assert check_valid_domain(section) == [] and section.points.shape[1] == 3
    assert count_boundary_components(section) == 1 and boundary_euler_characteristic(section) == 2
    assert 0 < signed_measures(section.points, section.cells).sum() <= 4 / 3 * np.pi * (1 - 0.05**2) ** 1.5
    node = mesh.points[np.argmin(np.linalg.norm(mesh.points, axis=1)), 3]
    for value in (node, node + 1e-12, node - 1e-12):
        assert check_valid_domain(slice_mesh(mesh, value)) == []
    cuts = np.linspace(-1.0, 1.0, 201)
    measures = [signed_measures(s.points, s.cells).sum() for s in (slice_mesh(mesh, cut) for cut in cuts)]
    assert np.trapezoid(measures, cuts) == pytest.approx(signed_measures(mesh.points, mesh.cells).sum(), rel=1e-3)
    assert len(slice_mesh(mesh, 1.5).cells) == 0


def test_a_section_of_a_3_d_mesh_is_a_2_d_mesh():
    """The same cut one dimension down: a 3-D ball's mesh at z = 0.3 is a valid disc (its boundary one loop)."""
    grid = sample_function(ball, -np.ones(3), np.ones(3), 0.05, margin=0.1)
    mesh = mesh_from_grid(grid, BitingParameters(radius=0.2), optimize=OptimizeParameters(optimize=0)).mesh
    section = slice_mesh(mesh, 0.3, axis=2)
    assert check_valid_domain(section) == [] and count_boundary_components(section) == 1
    assert 0 < signed_measures(section.points, section.cells).sum() <= np.pi * (1 - 0.3**2)


def test_topology_counts_a_ball_and_a_solid_torus_in_4d_alike_on_the_mesh_and_the_grid():
    """Beyond 3-D the boundary's Euler characteristic says nothing of tunnels (a closed 3-manifold's is 0), so the
    handles come from the domain's own (b1 - b2 in 4-D): the 4-ball none, the solid torus S^1 x B^3 one, the same on
    the mesh and on f's grid (the 3-D formula counted one handle on the 4-ball and refused its mesh)."""
    from bitemesh.core.mesh.betti import grid_topology, mesh_topology
    for shape, handles in (("ball", 0), ("torus", 1)):
        grid, result = meshed(shape, 4, 0.3)
        assert mesh_topology(result.mesh).describe() == f"1 part(s), {handles} handle(s), 0 void(s)"
        nodes = np.stack(np.meshgrid(*[grid.origin[d] + np.arange(n) * grid.spacing[d]
                                       for d, n in enumerate(grid.shape)], indexing="ij"), axis=-1)
        inside = (solid_torus if shape == "torus" else ball)(nodes.reshape(-1, 4)).reshape(grid.shape) > 0
        assert grid_topology(inside).describe() == f"1 part(s), {handles} handle(s), 0 void(s)"


def test_the_fidelity_measures_facets_of_any_dimension():
    """A 4-D mesh's boundary facets are tetrahedra: the nearest point on each (no sampled point of it nearer, and
    no vertex beyond the plane through it across the offset), its
    3-volume (the regular tetrahedron's sqrt(2)/12 a^3) and its normal (across its edges); and samples all round a
    point of a 3-sphere surround it in its tangent space, samples on one side of it do not."""
    from bitemesh.core.mesh.simplicial import facet_measures
    from bitemesh.core.steps.fidelity import closest_on_facets, facet_normals, surrounded
    rng = np.random.default_rng(0)
    corners = rng.normal(size=(40, 4, 4))
    points = 2 * rng.normal(size=(40, 4))
    nearest = closest_on_facets(points, corners)
    weights = rng.dirichlet(np.ones(4), size=20000)
    sampled = np.einsum("sv,mvi->msi", weights, corners)
    brute = np.linalg.norm(sampled - points[:, None], axis=2).min(axis=1)
    found = np.linalg.norm(nearest - points, axis=1)
    assert (found <= brute + 1e-12).all()
    # nearest on a convex polytope: no vertex lies beyond the plane through it across p - q (the optimality condition)
    assert (np.einsum("mi,mvi->mv", points - nearest, corners - nearest[:, None]) <= 1e-9).all()
    regular = np.eye(4)[None] * np.sqrt(0.5) * 2   # a regular tetrahedron of edge 2 in the hyperplane sum x = const
    assert facet_measures(regular)[0] == pytest.approx(np.sqrt(2) / 12 * 8)
    normals = facet_normals(corners)
    assert np.allclose(np.einsum("mvi,mi->mv", corners[:, 1:] - corners[:, :1], normals), 0, atol=1e-9)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1)
    sphere = rng.normal(size=(4000, 4))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    pole = np.array([[0.0, 0.0, 0.0, 1.0]])
    from scipy.spatial import cKDTree
    assert surrounded(pole, pole, sphere, cKDTree(sphere), np.array([0.5])).all()
    half = sphere[sphere[:, 0] > 0]
    assert not surrounded(pole, pole, half, cKDTree(half), np.array([0.5])).any()
