"""P1 finite elements (bitemesh.core.fem.assembly) and the solver check (bitemesh.core.fem.check): the quadrature, the
element matrices, Poisson on the unit ball converging at order 2, linear elasticity of a bar against its analytic
displacement and the patch test, the condition numbers against dense eigenvalues, and the optimizer's effect on them."""
from __future__ import annotations

from functools import cache
from itertools import product
from math import factorial

import numpy as np
import pytest
from scipy.spatial import Delaunay

import bitemesh
from bitemesh.core.fem import assembly as fem
from bitemesh.core.optimize.measures import boundary_nodes, mean_edge_length
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.check import FemParameters, fem_check, jacobi_scaled
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.mesh.topology import boundary_facets

from tests.builders import cube_mesh, positively_oriented, square_mesh

#: tight enough for the dense comparison (rtol 1e-6): the default 1e-4 is for speed on large meshes
TIGHT = FemParameters(tolerance=1e-8)


@pytest.fixture(scope="module")
def sphere(unit_sphere_samples):
    """sphere(cells, optimize): the unit sphere meshed by the pipeline, each mesh made once for the module."""
    points, normals = unit_sphere_samples
    return cache(lambda cells, optimize: bitemesh.mesh(bitemesh.Samples(points, normals), cells=cells,
                                                       optimize=optimize).mesh)


# --- the pieces -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_the_simplex_rule_integrates_every_monomial_of_its_degree(degree):
    barycentric, weights = fem.simplex_rule(degree)
    x = barycentric[:, 1:]   # the reference tetrahedron, volume 1/6
    for a, b, c in product(range(degree + 1), repeat=3):
        if a + b + c <= degree:
            exact = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3)
            assert np.sum(weights * x[:, 0] ** a * x[:, 1] ** b * x[:, 2] ** c) / 6 == pytest.approx(exact, rel=1e-12)


def test_the_element_matrices_know_constants_rigid_motions_and_uniform_strain():
    mesh = cube_mesh()
    x = mesh.points
    laplace = fem.laplace_matrix(x, mesh.cells)
    assert np.abs(laplace @ np.ones(8)).max() < 1e-14
    assert x[:, 0] @ laplace @ x[:, 0] == pytest.approx(1.0)        # integral of |grad x|^2 over the unit cube
    elasticity = fem.elasticity_matrix(x, mesh.cells, young=2.0, poisson=0.25)
    assert abs(elasticity - elasticity.T).max() < 1e-14
    for motion in [np.tile(axis, (8, 1)) for axis in np.eye(3)] + [np.cross(axis, x) for axis in np.eye(3)]:
        assert np.abs(elasticity @ motion.ravel()).max() < 1e-13
    strain = np.array([[1.0, 0.2, 0.0], [0.2, -0.3, 0.1], [0.0, 0.1, 0.5]])
    u = (x @ strain.T).ravel()
    lam, mu = fem.lame(2.0, 0.25)
    # twice the strain energy of the cube: lambda tr(eps)^2 + 2 mu eps : eps
    assert u @ elasticity @ u == pytest.approx(lam * np.trace(strain) ** 2 + 2 * mu * np.sum(strain ** 2))


@pytest.mark.parametrize("per_node", [1, 2, 3])
def test_the_assembly_pattern_sums_every_element_entry_where_a_coo_sum_does(per_node):
    # every entry of random element matrices, summed at (per_node a + i, per_node b + j) entry by entry, against
    # the pattern's CSR: same values, ascending columns, no duplicates, and reused for a second set of elements
    points = np.random.default_rng(2).random((60, 3))
    cells, n = Delaunay(points).simplices.astype(np.int64), len(points)
    size = 4 * per_node
    dofs = (per_node * cells[:, :, None] + np.arange(per_node)).reshape(len(cells), size)
    pattern = fem.Pattern.of(cells, n, per_node)
    for seed in (0, 1):
        elements = np.random.default_rng(seed).normal(size=(len(cells), size, size))
        expected = np.zeros((per_node * n, per_node * n))
        np.add.at(expected, (dofs[:, :, None], dofs[:, None, :]), elements)
        matrix = pattern.assemble(elements)
        assert np.allclose(matrix.toarray(), expected, rtol=0, atol=1e-12)
        assert all(np.all(np.diff(matrix.indices[start:end]) > 0)
                   for start, end in zip(matrix.indptr[:-1], matrix.indptr[1:]))
        neighbours = {(a, b) for cell in cells for a in cell for b in cell}
        assert matrix.nnz == per_node ** 2 * len(neighbours)


def test_zero_volume_and_2d_meshes_are_refused():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    with pytest.raises(InvalidInputError, match="zero volume.*cell 0"):
        fem.basis_gradients(points, np.array([[0, 1, 2, 3]]))
    with pytest.raises(InvalidInputError, match="needs tetrahedra.*triangles"):
        fem_check(square_mesh())
    with pytest.raises(InvalidInputError, match="every node lies on the boundary.*finer mesh"):
        fem_check(cube_mesh())


def test_unused_points_are_left_out(sphere):
    mesh = sphere(2000, 1)
    padded = Mesh(np.vstack([mesh.points, [[5.0, 5.0, 5.0]]]), mesh.cells)
    with_unused, plain = fem_check(padded), fem_check(mesh)
    assert with_unused.n_points == plain.n_points == len(mesh.points)
    assert with_unused.laplace.lambda_max == pytest.approx(plain.laplace.lambda_max, rel=1e-9)


# --- Poisson on the unit ball ----------------------------------------------------------------------------------


def poisson_error(mesh) -> tuple[float, float]:
    """(mean edge length, L2 error) of P1 for -laplace u = 1, u = 0 on the boundary, against u = (1 - r^2) / 6.

    The boundary nodes are first put on the unit sphere: the mesher leaves them where the MPU fit of the samples
    has f = 0, about 2e-3 off (a fixed error of the fit, which does not shrink with h and would flatten the rate).
    With the nodes on the sphere, the polyhedron differs from the ball by O(h^2), the order of the P1 error itself.
    """
    points = mesh.points.copy()
    boundary = boundary_nodes(mesh.cells, len(points))
    points[boundary] /= np.linalg.norm(points[boundary], axis=1, keepdims=True)
    matrix, rhs, u = fem.eliminate(fem.laplace_matrix(points, mesh.cells), fem.source_load(points, mesh.cells),
                                   boundary)
    u[~boundary] = fem.solve(matrix, rhs).solution
    error = fem.l2_error(points, mesh.cells, u, lambda x: (1 - np.sum(x * x, axis=1)) / 6)
    return mean_edge_length(points, mesh.cells), error


def test_poisson_on_the_unit_ball_converges_at_order_2(sphere):
    meshes = [sphere(cells, 0) for cells in (2000, 6000, 20000)]   # without the optimizer: 3 s, not 15
    h, error = np.array([poisson_error(mesh) for mesh in meshes]).T
    rate = np.polyfit(np.log(h), np.log(error), 1)[0]
    # P1 in L2 is O(h^2) for this smooth solution (Aubin-Nitsche), the boundary's chord error is O(h^2) too; the
    # three meshes span h by a factor 2.3 only, and unstructured meshes of different sizes are not refinements of
    # one another, so the fitted slope may stray from 2 by a few tenths: [1.8, 2.3] as the issue asks.
    assert 1.8 <= rate <= 2.3, (h, error, rate)   # measured: 1.99 (h 0.298, 0.199, 0.132)
    assert error[-1] < 0.05 * np.sqrt(4 / 3 * np.pi) * 1 / 6   # well under 5 % of the norm of u (~0.34)


# --- linear elasticity -------------------------------------------------------------------------------------------


def bar_mesh(length=4.0, n=(8, 2, 2)) -> Mesh:
    """The box [0, length] x [0, 1] x [0, 1] in n[0] x n[1] x n[2] cubes of 6 tetrahedra each (Kuhn's subdivision,
    as tests/builders.cube_mesh), the nodes slightly perturbed inside so that the cells are not all alike."""
    axes = [np.linspace(0, size, count + 1) for size, count in zip((length, 1.0, 1.0), n)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    index = np.arange(len(grid)).reshape([count + 1 for count in n])
    cube = cube_mesh()
    corners = cube.points.astype(int)
    cells = []
    for i, j, k in product(*(range(count) for count in n)):
        nodes = index[i + corners[:, 0], j + corners[:, 1], k + corners[:, 2]]
        cells.append(nodes[cube.cells])
    inside = np.all((grid > 1e-9) & (grid < np.array([length, 1, 1]) - 1e-9), axis=1)
    grid[inside] += np.random.default_rng(1).uniform(-0.05, 0.05, (int(inside.sum()), 3))
    return Mesh(grid, positively_oriented(grid, np.vstack(cells)))


def test_a_bar_under_traction_has_the_analytic_displacement():
    """Uniaxial traction sigma on x = L, rollers on x = 0, y = 0 and z = 0 (each holds its normal component): the
    exact solution u = (sigma x / E, -nu sigma y / E, -nu sigma z / E) is linear, which P1 represents exactly, so
    the error is round-off."""
    length, young, nu, sigma = 4.0, 200.0, 0.3, 5.0
    mesh = bar_mesh(length)
    x = mesh.points
    facets = boundary_facets(mesh.cells)
    end = facets[np.all(np.isclose(x[facets, 0], length), axis=1)]
    assert len(end) == 2 * 2 * 2   # two triangles per end square
    rhs = fem.traction_load(x, end, [sigma, 0.0, 0.0]).ravel()
    assert rhs.sum() == pytest.approx(sigma * 1.0)   # the force on the unit end face
    fixed = np.zeros((len(x), 3), bool)
    for axis in range(3):
        fixed[np.isclose(x[:, axis], 0.0), axis] = True
    matrix, reduced_rhs, u = fem.eliminate(fem.elasticity_matrix(x, mesh.cells, young, nu), rhs, fixed.ravel())
    u[~fixed.ravel()] = fem.solve(matrix, reduced_rhs, method="direct").solution
    exact = sigma / young * x * np.array([1.0, -nu, -nu])
    error = np.abs(u.reshape(-1, 3) - exact).max() / np.abs(exact).max()
    assert error < 1e-10, error   # measured: 1e-14 or so


def test_the_patch_test_on_a_pipeline_mesh(sphere):
    """Any linear displacement imposed on the boundary of an unstructured mesh, no load: P1 gives it exactly inside
    (the patch test), by CG as well as by the direct solver."""
    mesh = sphere(2000, 1)
    x = mesh.points
    field = np.array([[0.01, 0.02, -0.03], [0.0, -0.02, 0.01], [0.015, 0.0, 0.005]])
    exact = (x @ field.T + np.array([0.1, -0.2, 0.3])).ravel()
    fixed = np.repeat(boundary_nodes(mesh.cells, len(x)), 3)
    matrix, rhs, u = fem.eliminate(fem.elasticity_matrix(x, mesh.cells, 1.0, 0.45), np.zeros(3 * len(x)), fixed,
                                   exact)
    for method in ("direct", "cg"):
        u[~fixed] = fem.solve(matrix, rhs, method=method, rtol=1e-13).solution
        assert np.abs(u - exact).max() / np.abs(exact).max() < 1e-10, method


# --- the solver check ---------------------------------------------------------------------------------------------


def dense_extremes(matrix) -> tuple[float, float]:
    values = np.linalg.eigvalsh(matrix.toarray())
    return values[0], values[-1]


def test_the_conditioning_agrees_with_dense_eigenvalues(sphere):
    mesh = sphere(2000, 0)
    report = fem_check(mesh, TIGHT)
    x, cells = mesh.points, mesh.cells
    fixed = boundary_nodes(cells, len(x))
    laplace = fem.eliminate(fem.laplace_matrix(x, cells), np.zeros(len(x)), fixed)[0]
    elasticity = fem.eliminate(fem.elasticity_matrix(x, cells), np.zeros(3 * len(x)), np.repeat(fixed, 3))[0]
    assert report.laplace.size == laplace.shape[0] > 50 and report.elasticity.size == 3 * laplace.shape[0]
    for measured, matrix in ((report.laplace, laplace), (report.elasticity, elasticity)):
        expected = (*dense_extremes(matrix), *dense_extremes(jacobi_scaled(matrix)))
        got = (measured.lambda_min, measured.lambda_max, measured.jacobi_min, measured.jacobi_max)
        np.testing.assert_allclose(got, expected, rtol=1e-6)


def test_the_optimized_sphere_conditions_better_and_the_sliver_is_named(sphere):
    cells = BitingParameters().cells   # the default size, at which the issue states its figure
    plain, optimized = (fem_check(sphere(cells, switch)) for switch in (0, 1))
    ratio = plain.laplace.condition / optimized.laplace.condition
    # the issue: about 5x better conditioning than the unoptimized mesh on a sphere.  lambda min is the domain's
    # (it moves by under 2 %: the same nodes), lambda max that of the stiffest cell, which the sliver removal
    # bounds: the ratio is set by the worst sliver of the plain mesh, so it varies with the mesh (measured 18x here,
    # 2.8x at 6,000 cells); the bound is the figure at the default size.
    assert ratio >= 5, (plain.laplace, optimized.laplace)
    assert optimized.laplace.jacobi_condition < plain.laplace.jacobi_condition
    assert optimized.elasticity.condition < plain.elasticity.condition
    assert plain.laplace.lambda_min == pytest.approx(optimized.laplace.lambda_min, rel=0.02)
    assert optimized.reference["iterations"] < plain.reference["iterations"]
    # the cell named first on the plain mesh is its stiffest element: the largest eigenvalue of its element matrix
    mesh = sphere(cells, 0)
    elements = fem.laplace_elements(*fem.basis_gradients(mesh.points, mesh.cells))
    stiffest = int(np.argmax(np.linalg.eigvalsh(elements)[:, -1]))
    assert plain.stiff_cells[0].index == stiffest
    assert plain.stiff_cells[0].min_dihedral < 10 and plain.stiff_cells[0].element_condition > 100
    assert len(plain.stiff_cells) == FemParameters().worst
    text = str(plain)
    assert f"cell {stiffest}" in text and "laplace K" in text and "cg+jacobi" in text


def test_the_check_without_elasticity(sphere):
    report = fem_check(sphere(2000, 1), FemParameters(elasticity=0, worst=0))
    assert report.elasticity is None and report.stiff_cells == []
    assert "elasticity" not in str(report) and report.reference["residual"] < 1e-9
