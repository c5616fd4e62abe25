"""Linear (P1) finite elements on tetrahedra: the stiffness matrices of -laplace and of isotropic linear
elasticity, load vectors, Dirichlet conditions by elimination, the solve, and an exact quadrature for errors.

Everything is vectorised over cells: the gradients of the barycentric basis come from the inverse of each cell's
edge matrix, the element matrices are stacked as (m, d, d) arrays and summed into a scipy.sparse CSR matrix.
Elasticity numbers its degrees of freedom node by node: dof 3 i + c is the component c of node i.  The :mod:`fem_check
<bitemesh.core.fem.check>` module measures the conditioning of these matrices.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from itertools import combinations_with_replacement
from math import factorial

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg

from ..errors import InvalidInputError, MeshingError


def basis_gradients(points: np.ndarray, cells: np.ndarray):
    """The gradients of the four barycentric basis functions of each tetrahedron, and its volume.

    Parameters
    ----------
    points : (n, 3) float64, input units
    cells : (m, 4) int

    Returns
    -------
    gradients : (m, 4, 3) float64, 1 / input units; row i is grad lambda_i (they sum to 0)
    volumes : (m,) float64, input units^3, > 0

    Raises :class:`InvalidInputError` for a cell of zero volume, to round-off (its gradients do not exist).
    """
    corners = points[cells]
    edges = corners[:, 1:] - corners[:, :1]          # rows: v1 - v0, v2 - v0, v3 - v0
    volumes = np.abs(np.linalg.det(edges)) / 6.0
    longest = np.einsum("mij,mij->mi", edges, edges).max(axis=1) ** 1.5
    flat = np.flatnonzero(~(volumes > 1e-14 * longest))   # flat to round-off: V / l^3 of a regular tet is 0.12
    if flat.size:
        raise InvalidInputError(f"cells: {flat.size} cells have zero volume (first: cell {flat[0]}); P1 elements "
                                "need non-degenerate tetrahedra; repair the mesh (bitemesh quality lists its defects)")
    # x - v0 = edges^T lambda', so grad lambda_i (i = 1..3) is column i of edges^-1
    tail = np.linalg.inv(edges).transpose(0, 2, 1)
    return np.concatenate([-tail.sum(axis=1, keepdims=True), tail], axis=1), volumes


def laplace_elements(gradients: np.ndarray, volumes: np.ndarray) -> np.ndarray:
    """(m, 4, 4) element stiffness matrices of -laplace: volume grad lambda_a . grad lambda_b, input units."""
    return volumes[:, None, None] * np.einsum("mai,mbi->mab", gradients, gradients)


def lame(young: float, poisson: float):
    """Lamé's (lambda, mu) from Young's modulus (any unit of stress) and Poisson's ratio (-1 < nu < 1/2)."""
    return young * poisson / ((1 + poisson) * (1 - 2 * poisson)), young / (2 * (1 + poisson))


def elasticity_elements(gradients: np.ndarray, volumes: np.ndarray, young: float = 1.0,
                        poisson: float = 0.3) -> np.ndarray:
    """(m, 12, 12) element stiffness matrices of isotropic linear elasticity, rows and columns 3 a + i (node a,
    component i): volume (lambda d_i phi_a d_j phi_b + mu d_j phi_a d_i phi_b + mu delta_ij grad phi_a . grad phi_b),
    units of ``young`` x input units."""
    lam, mu = lame(young, poisson)
    weighted = volumes[:, None, None] * gradients
    outer = weighted[:, :, :, None, None] * gradients[:, None, None, :, :]     # volume d_i phi_a d_j phi_b
    block = lam * outer
    block += mu * outer.transpose(0, 1, 4, 3, 2)                              # + mu d_j phi_a d_i phi_b
    dots = mu * np.einsum("mai,mbi->mab", weighted, gradients)
    for i in range(3):
        block[:, :, i, :, i] += dots
    return block.reshape(len(volumes), 12, 12)


@dataclass(frozen=True)
class Pattern:
    """Where each entry of the element matrices of a mesh's cells lands in the CSR data of their sum, found once
    for the cells and reused by every matrix assembled on them (the template fit assembles its stiffness each
    round: summing 14 million entries by scipy's COO to CSR took 0.5 s each time).  Degrees of freedom node by node:
    dof ``per_node`` i + c is the component c of node i; each row's columns ascending.

    Attributes
    ----------
    indptr : (N + 1,), indices : (nnz,) the CSR structure, N = per_node x the nodes
    position : (m, k per_node, k per_node) where each element entry is summed into the CSR data
    """

    indptr: np.ndarray
    indices: np.ndarray
    position: np.ndarray

    @classmethod
    def of(cls, cells: np.ndarray, n_points: int, per_node: int = 1) -> "Pattern":
        """The pattern of (m, k) ``cells`` on ``n_points`` nodes, ``per_node`` degrees of freedom each."""
        m, k, c = len(cells), cells.shape[1], per_node
        pairs, pair_of = np.unique(np.repeat(cells, k, axis=1) * n_points + np.tile(cells, (1, k)),
                                   return_inverse=True)            # node pairs (a, b) of every cell, row major
        rows, columns = pairs // n_points, pairs % n_points
        degree = np.bincount(rows, minlength=n_points)
        starts = np.r_[0, np.cumsum(degree)]
        rank = np.arange(len(pairs)) - starts[rows]                 # b's place among a's neighbours
        i, j = np.arange(c)[:, None], np.arange(c)[None, :]
        # the entry (c a + i, c b + j) sits at c^2 starts[a] + c degree[a] i + c rank + j
        at = (c * c * starts[rows])[:, None, None] + (c * degree[rows])[:, None, None] * i + c * rank[:, None, None] + j
        total = c * c * len(pairs)
        dtype = np.int32 if total < 2 ** 31 else np.int64
        indices = np.empty(total, dtype)
        indices[at.ravel()] = np.broadcast_to(c * columns[:, None, None] + j, at.shape).ravel()
        indptr = np.r_[(c * c * starts[:-1, None] + c * degree[:, None] * np.arange(c)).ravel(), total]
        position = at[pair_of.reshape(m, k, k)].transpose(0, 1, 3, 2, 4).reshape(m, k * c, k * c)
        return cls(indptr.astype(dtype), indices, position)   # position intp: bincount would cast it each time

    def assemble(self, elements: np.ndarray) -> sparse.csr_matrix:
        """The CSR sum of the (m, d, d) element matrices."""
        data = np.bincount(self.position.ravel(), elements.ravel(), minlength=len(self.indices))
        size = len(self.indptr) - 1
        matrix = sparse.csr_matrix((data, self.indices, self.indptr), shape=(size, size))
        matrix.has_sorted_indices = True
        return matrix


def assemble(elements: np.ndarray, cells: np.ndarray, n_points: int, per_node: int = 1) -> sparse.csr_matrix:
    """The CSR sum of the (m, k per_node, k per_node) element matrices of (m, k) ``cells`` on ``n_points`` nodes
    (:class:`Pattern`)."""
    return Pattern.of(cells, n_points, per_node).assemble(elements)


def laplace_matrix(points: np.ndarray, cells: np.ndarray) -> sparse.csr_matrix:
    """(n, n) P1 stiffness matrix of -laplace on the mesh (input units)."""
    gradients, volumes = basis_gradients(points, cells)
    return assemble(laplace_elements(gradients, volumes), cells, len(points))


def elasticity_matrix(points: np.ndarray, cells: np.ndarray, young: float = 1.0,
                      poisson: float = 0.3) -> sparse.csr_matrix:
    """(3 n, 3 n) P1 stiffness matrix of isotropic linear elasticity (dof 3 i + c)."""
    gradients, volumes = basis_gradients(points, cells)
    return assemble(elasticity_elements(gradients, volumes, young, poisson), cells, len(points), per_node=3)


def source_load(points: np.ndarray, cells: np.ndarray, source=1.0) -> np.ndarray:
    """The load vector of a constant source: (n,) for a scalar ``source``, (n, 3) for a body force (3,), each
    vertex receiving a quarter of its cells' volume times it (exact for a constant)."""
    volumes = np.abs(np.linalg.det(points[cells[:, 1:]] - points[cells[:, :1]])) / 6.0
    share = np.bincount(cells.ravel(), np.repeat(volumes / 4.0, 4), len(points))
    return share * source if np.ndim(source) == 0 else share[:, None] * np.asarray(source, dtype=np.float64)


def traction_load(points: np.ndarray, triangles: np.ndarray, traction, n_points: int | None = None) -> np.ndarray:
    """(n, 3) nodal forces of a traction (force per area) on boundary triangles: (3,) constant or (t, 3) one per
    triangle; each vertex receives a third of its triangles' area times it (exact for a constant traction)."""
    corners = points[triangles]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    forces = areas[:, None] * np.broadcast_to(np.asarray(traction, dtype=np.float64), (len(triangles), 3)) / 3.0
    n = len(points) if n_points is None else n_points
    return np.stack([np.bincount(triangles.ravel(), np.repeat(forces[:, c], 3), n) for c in range(3)], axis=1)


def eliminate(matrix: sparse.csr_matrix, rhs: np.ndarray, fixed: np.ndarray, values=0.0):
    """Dirichlet conditions by elimination, keeping the system symmetric.

    Parameters
    ----------
    matrix : (N, N) sparse; rhs : (N,)
    fixed : (N,) bool, the degrees of freedom whose value is given; values : scalar or (N,) their values

    Returns
    -------
    reduced : (f, f) CSR, the rows and columns of the free dofs
    reduced_rhs : (f,) rhs - matrix u_fixed, at the free dofs
    full : (N,) the given values at the fixed dofs, 0 elsewhere (put the solution at ``~fixed``)
    """
    full = np.where(fixed, np.broadcast_to(np.asarray(values, dtype=np.float64), fixed.shape), 0.0)
    free = ~fixed
    if not free.any():
        raise InvalidInputError("fixed: every degree of freedom is fixed; there is nothing to solve")
    reduced = matrix[free][:, free].tocsr()
    return reduced, (rhs - matrix @ full)[free], full


def harmonic(matrix: sparse.csr_matrix, fixed: np.ndarray, values, rtol: float = 1e-10):
    """(N,) u with ``matrix`` u = 0 at the free dofs and u = ``values`` at the ``fixed`` (N,) ones (a Laplace
    problem's stiffness: the harmonic function with those Dirichlet values), by Jacobi-CG to ``rtol``; and its
    :class:`Solve`."""
    reduced, rhs, full = eliminate(matrix, np.zeros(matrix.shape[0]), fixed, values)
    found = solve(reduced, rhs, method="cg", rtol=rtol)
    full[~fixed] = found.solution
    return full, found


@dataclass(frozen=True)
class Solve:
    """A linear solve: the solution, how it went and what it cost.

    ``iterations`` is 0 for the direct solver; ``residual`` is |b - A x| / |b|; ``seconds`` wall time.
    """

    solution: np.ndarray
    method: str
    iterations: int
    residual: float
    seconds: float


def solve(matrix: sparse.csr_matrix, rhs: np.ndarray, method: str = "cg", rtol: float = 1e-10,
          max_iterations: int = 20000) -> Solve:
    """Solve the symmetric positive definite system ``matrix x = rhs``.

    ``method``: "cg", conjugate gradients with the Jacobi (diagonal) preconditioner from x = 0, stopped at a
    relative residual ``rtol`` or after ``max_iterations`` (then :class:`MeshingError`); "direct": SuperLU (scipy
    spsolve).
    """
    start = time.perf_counter()
    if method == "direct":
        x, iterations = splinalg.spsolve(matrix.tocsc(), rhs), 0
    elif method == "cg":
        x, iterations = _jacobi_cg(matrix, rhs, rtol, max_iterations)
    else:
        raise InvalidInputError(f"method must be 'cg' or 'direct', got {method!r}")
    seconds = time.perf_counter() - start
    norm = np.linalg.norm(rhs)
    residual = float(np.linalg.norm(rhs - matrix @ x) / norm) if norm > 0 else 0.0
    return Solve(x, method, iterations, residual, seconds)


def _jacobi_cg(matrix, rhs, rtol, max_iterations):
    """Preconditioned CG (Hestenes-Stiefel with M = diag(A)); the dot products by einsum, not BLAS, whose threads
    cost more than they save on vectors of this size when the cores are shared (6x measured on 2 cores)."""
    inverse_diagonal = 1.0 / matrix.diagonal()
    x, residual = np.zeros_like(rhs), rhs.copy()
    z = inverse_diagonal * residual
    direction, rz = z.copy(), np.einsum("i,i", residual, z)
    target = rtol * np.sqrt(np.einsum("i,i", rhs, rhs))
    for iteration in range(1, max_iterations + 1):
        product = matrix @ direction
        step = rz / np.einsum("i,i", direction, product)
        x += step * direction
        residual -= step * product
        if np.sqrt(np.einsum("i,i", residual, residual)) <= target:
            return x, iteration
        z = inverse_diagonal * residual
        rz, previous = np.einsum("i,i", residual, z), rz
        direction = z + (rz / previous) * direction
    raise MeshingError(f"cg: no convergence to rtol {rtol:g} in {max_iterations} iterations; the mesh is too "
                       "ill-conditioned (bitemesh fem names its stiffest cells), or use method='direct'")


def simplex_rule(degree: int):
    """A quadrature rule on tetrahedra exact for polynomials of ``degree`` (Grundmann and Möller 1978, odd degree
    2 s + 1 >= ``degree``; some weights are negative).

    Returns
    -------
    barycentric : (q, 4) float64, the points in barycentric coordinates
    weights : (q,) float64, summing to 1 (multiply by the cell's volume)
    """
    s = max(degree, 0) // 2
    d, n = 2 * s + 1, 3
    points, weights = [], []
    for i in range(s + 1):
        weight = (-1) ** i * (d + n - 2 * i) ** d / (4.0 ** s * factorial(i) * factorial(d + n - i))
        for chosen in combinations_with_replacement(range(n + 1), s - i):
            beta = np.bincount(np.array(chosen, dtype=np.int64), minlength=n + 1)
            points.append((2 * beta + 1) / (d + n - 2 * i))
            weights.append(weight)
    weights = np.array(weights)
    return np.array(points), weights / weights.sum()


def l2_error(points: np.ndarray, cells: np.ndarray, nodal: np.ndarray, exact, degree: int = 5) -> float:
    """The L2 norm over the mesh of (P1 interpolant of ``nodal`` (n,)) - ``exact``, by :func:`simplex_rule` of
    ``degree`` on every cell; ``exact``: callable (q, 3) -> (q,).  For a quadratic ``exact`` the default rule is
    exact: the error is a quadratic on each cell, its square a quartic."""
    barycentric, weights = simplex_rule(degree)
    corners = points[cells]                                               # (m, 4, 3)
    where = np.einsum("qa,mai->mqi", barycentric, corners)                # (m, q, 3)
    approximate = np.einsum("qa,ma->mq", barycentric, nodal[cells])
    error = approximate - exact(where.reshape(-1, 3)).reshape(approximate.shape)
    volumes = np.abs(np.linalg.det(corners[:, 1:] - corners[:, :1])) / 6.0
    return float(np.sqrt(np.sum(volumes * (error ** 2 @ weights))))
