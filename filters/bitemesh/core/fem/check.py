"""The solver check of a tetrahedral mesh: how well its P1 stiffness matrices are conditioned, which cells make them
so, and a reference problem solved on it.

Both matrices are reduced by the Dirichlet condition of the reference problem: every boundary node fixed (u = 0 for
-laplace, a clamped boundary for elasticity, which also removes the rigid motions).  Their largest eigenvalue comes
from ARPACK (scipy eigsh), the smallest from LOBPCG started from the reference solution; the Jacobi-scaled
condition, of D^-1/2 A D^-1/2 with D the diagonal, is the one that preconditioned CG sees.  The largest eigenvalue is
set by the stiffest cells (slivers, small cells); the cells named are those that hold the largest share of its
eigenvector's energy, by their index in the mesh (the cell ids of the written file, as ParaView shows them).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg

from . import assembly as fem
from ..optimize.measures import boundary_nodes
from ..errors import InvalidInputError, MeshingError
from ..parameters import Parameters, parameter
from ..mesh.quality import dihedral_angles, radius_ratio
from ..mesh.validity import _check_mesh


@dataclass(frozen=True)
class FemParameters(Parameters):
    """Solver check: the material of the elasticity matrix and how many cells to name."""

    young: float = parameter(1.0, "Young's modulus E of the elasticity matrix (its eigenvalues scale with E, its "
                             "condition does not)", unit="units of stress", low=0, low_open=True)
    poisson: float = parameter(0.3, "Poisson's ratio nu of the elasticity matrix; near 0.5 (incompressible) P1 "
                               "locks and the condition grows", low=-1, high=0.5, low_open=True, high_open=True)
    worst: int = parameter(5, "how many of the cells that dominate the largest eigenvalue to list", low=0, high=1000,
                           integer=True)
    elasticity: int = parameter(1, "1 also checks linear elasticity (3 dofs per node: about 10x the time of "
                                "-laplace); 0 checks -laplace only", low=0, high=1, integer=True)
    tolerance: float = parameter(1e-4, "LOBPCG stops when the residual of the smallest eigenpair is below this "
                                 "fraction of it (on a 136k-cell sphere 1e-4 gave lambda min within 5e-5)", low=0,
                                 high=0.1, low_open=True)


@dataclass(frozen=True)
class Conditioning:
    """Extreme eigenvalues and condition numbers of a Dirichlet-reduced stiffness matrix.

    ``lambda_min``/``lambda_max``: of the matrix (units of the matrix: input units for -laplace, E x input units for
    elasticity); ``jacobi_*``: of D^-1/2 A D^-1/2 (no unit); ``size``: free degrees of freedom; ``seconds``: wall.
    """

    size: int
    lambda_min: float
    lambda_max: float
    jacobi_min: float
    jacobi_max: float
    seconds: float

    @property
    def condition(self) -> float:
        return self.lambda_max / self.lambda_min

    @property
    def jacobi_condition(self) -> float:
        return self.jacobi_max / self.jacobi_min


@dataclass(frozen=True)
class StiffCell:
    """A cell that dominates the largest eigenvalue of -laplace: ``share`` of that eigenvector's energy (0..1), its
    radius ratio, its smallest dihedral angle (degrees) and its element condition (largest / smallest non-zero
    eigenvalue of its element matrix; 1 for the regular tetrahedron)."""

    index: int
    share: float
    radius_ratio: float
    min_dihedral: float
    element_condition: float


@dataclass(frozen=True)
class FemReport:
    """What :func:`fem_check` measured (``str()`` gives :func:`format_report`).

    ``reference``: -laplace u = 1, u = 0 on the boundary, by Jacobi-preconditioned CG (its solution's ``max_u`` in
    input units^2); ``elasticity_solve``: a unit body force on the clamped body, the same solver; ``elasticity``
    and ``elasticity_solve`` are None when the check left elasticity out.
    """

    n_points: int
    n_cells: int
    n_boundary_nodes: int
    laplace: Conditioning
    elasticity: Conditioning | None
    stiff_cells: list
    reference: dict
    elasticity_solve: dict | None

    def __str__(self) -> str:
        return format_report(self)


def largest_eigenvalue(matrix: sparse.spmatrix, tol: float = 1e-8):
    """The largest eigenvalue of a symmetric sparse matrix and its eigenvector (size,): ARPACK, which='LA'."""
    value, vector = splinalg.eigsh(matrix, k=1, which="LA", tol=tol)
    return float(value[0]), vector[:, 0]


def smallest_eigenvalue(matrix: sparse.spmatrix, guesses: np.ndarray, tol: float = 1e-4) -> float:
    """The smallest eigenvalue of a symmetric positive definite sparse matrix: LOBPCG with the Jacobi preconditioner
    from the (size, k) ``guesses``, stopped when each residual |A x - lambda x| falls below ``tol`` |A| |x| (measured
    at tol 1e-4 on the sphere: lambda min within 5e-5 relative at 136k cells, 2e-6 at 10k).

    The guesses are what makes it cheap: the solution of -laplace u = 1 is close to the first mode of -laplace, and u
    times the six rigid motions spans the first modes of a clamped body (multiple on a ball: a block of one would
    stall).  Shift-invert ARPACK needs a SuperLU factorisation instead, 22 s for -laplace on a 136k-cell sphere
    (21k dofs), against 0.5 s here.
    """
    inverse_diagonal = 1.0 / matrix.diagonal()
    jacobi = splinalg.LinearOperator(matrix.shape, matvec=lambda v: inverse_diagonal * v.ravel(),
                                     matmat=lambda block: inverse_diagonal[:, None] * block, dtype=np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)   # lobpcg warns, and returns its best, when it does not converge
        try:
            values = splinalg.lobpcg(matrix, guesses, M=jacobi, tol=tol, maxiter=MAX_ITERATIONS, largest=False)[0]
        except UserWarning as warning:
            raise MeshingError(f"lobpcg: the smallest eigenvalue did not converge to tol {tol:g} in "
                               f"{MAX_ITERATIONS} iterations ({str(warning).splitlines()[0]}); loosen --tolerance or "
                               "check the mesh for loose parts") from None
    return float(np.min(values))


#: the most LOBPCG iterations (measured: 66-155 with the guesses of :func:`fem_check`, sphere 10k-136k cells)
MAX_ITERATIONS = 2000


def jacobi_scaled(matrix: sparse.spmatrix) -> sparse.csr_matrix:
    """D^-1/2 A D^-1/2, with D the diagonal of A (unit diagonal)."""
    scale = sparse.diags(1.0 / np.sqrt(matrix.diagonal()))
    return (scale @ matrix @ scale).tocsr()


def conditioning(matrix: sparse.spmatrix, guesses: np.ndarray, tol: float = 1e-4):
    """:class:`Conditioning` of ``matrix`` and of its Jacobi scaling, and the eigenvector (size,) of the largest
    eigenvalue of ``matrix``; ``guesses`` (size, k) of the smallest (see :func:`smallest_eigenvalue`)."""
    start = time.perf_counter()
    high, vector = largest_eigenvalue(matrix)
    low = smallest_eigenvalue(matrix, guesses, tol)
    scaled, root = jacobi_scaled(matrix), np.sqrt(matrix.diagonal())
    jacobi_high = largest_eigenvalue(scaled)[0]
    jacobi_low = smallest_eigenvalue(scaled, guesses * root[:, None], tol)   # x of A is D^1/2 x of the scaled
    return Conditioning(matrix.shape[0], low, high, jacobi_low, jacobi_high, time.perf_counter() - start), vector


def element_condition(laplace_elements: np.ndarray) -> np.ndarray:
    """(m,) largest / second smallest eigenvalue of each (m, 4, 4) element matrix of -laplace (the smallest, 0,
    belongs to the constants): a shape measure, 1 for the regular tetrahedron, unbounded for a sliver."""
    values = np.linalg.eigvalsh(laplace_elements)
    return values[:, -1] / values[:, 1]


def stiff_cells(points, cells, elements, free, vector, count: int) -> list:
    """The ``count`` cells with the largest share of the energy v^T A v of the eigenvector ``vector`` (given at
    the ``free`` nodes, zero at the fixed ones), as :class:`StiffCell`, largest first."""
    if count == 0:
        return []
    full = np.zeros(len(free))
    full[free] = vector
    local = full[cells]
    energy = np.einsum("ma,mab,mb->m", local, elements, local)
    order = np.argsort(-energy, kind="stable")[:count]
    share = energy[order] / energy.sum()
    q = radius_ratio(points, cells[order])
    angles = np.nan_to_num(dihedral_angles(points, cells[order]).min(axis=1))
    kappa = element_condition(elements[order])
    return [StiffCell(int(i), float(s), float(a), float(b), float(c)) for i, s, a, b, c in
            zip(order, share, q, angles, kappa)]


def fem_check(mesh, parameters: FemParameters = FemParameters()) -> FemReport:
    """Assemble P1 -laplace and linear elasticity on a tetrahedral mesh, measure their conditioning, name the cells
    that dominate it and solve the reference problems.

    Parameters
    ----------
    mesh : Mesh with (n, 3) points and (m, 4) cells (orientation free); unused points are ignored
    parameters : :class:`FemParameters`

    Raises :class:`InvalidInputError` for a 2D mesh, a mesh without cells or with a zero-volume cell.
    """
    points, cells = _check_mesh(mesh)
    if points.shape[1] != 3 or len(cells) == 0:
        kind = "no cells" if len(cells) == 0 else "triangles (2D)"
        raise InvalidInputError(f"mesh: the solver check needs tetrahedra, got {kind}; mesh a volume first")
    gradients, volumes = fem.basis_gradients(points, cells)
    used = np.zeros(len(points), bool)
    used[cells.ravel()] = True
    boundary = boundary_nodes(cells, len(points))
    fixed = boundary | ~used
    if fixed.all():
        raise InvalidInputError("mesh: every node lies on the boundary, so the reduced matrices are empty; the "
                                "solver check needs interior nodes (a finer mesh)")
    laplace_elements = fem.laplace_elements(gradients, volumes)
    laplace = fem.assemble(laplace_elements, cells, len(points))
    reduced, rhs, bubble = fem.eliminate(laplace, fem.source_load(points, cells), fixed)
    reference = fem.solve(reduced, rhs)
    bubble[~fixed] = reference.solution
    laplace_conditioning, vector = conditioning(reduced, reference.solution[:, None], parameters.tolerance)
    elasticity_conditioning, elastic = None, None
    if parameters.elasticity:
        elasticity = fem.assemble(fem.elasticity_elements(gradients, volumes, parameters.young, parameters.poisson),
                                  cells, len(points), per_node=3)
        body = fem.source_load(points, cells, np.array([0.0, 0.0, -1.0])).ravel()
        free = ~np.repeat(fixed, 3)
        elastic_reduced, elastic_rhs, _ = fem.eliminate(elasticity, body, ~free)
        elastic = fem.solve(elastic_reduced, elastic_rhs)
        elasticity_conditioning = conditioning(elastic_reduced, rigid_bubbles(points, bubble)[free],
                                               parameters.tolerance)[0]
    return FemReport(
        n_points=int(used.sum()), n_cells=len(cells), n_boundary_nodes=int(boundary.sum()),
        laplace=laplace_conditioning, elasticity=elasticity_conditioning,
        stiff_cells=stiff_cells(points, cells, laplace_elements, ~fixed, vector, parameters.worst),
        reference=_solve_summary(reference, max_u=float(bubble.max())),
        elasticity_solve=None if elastic is None else _solve_summary(elastic))


def rigid_bubbles(points: np.ndarray, bubble: np.ndarray) -> np.ndarray:
    """(3 n, 6) the nodal ``bubble`` (n,) times each rigid motion (three translations, three rotations about the
    centroid), dof 3 i + c: guesses of the first modes of a clamped body."""
    offset = points - points.mean(axis=0)
    motions = [np.broadcast_to(axis, points.shape) for axis in np.eye(3)] + [np.cross(axis, offset)
                                                                          for axis in np.eye(3)]
    return np.stack([(bubble[:, None] * motion).ravel() for motion in motions], axis=1)


def _solve_summary(result: fem.Solve, **extra) -> dict:
    return {"method": "cg+jacobi", "iterations": result.iterations, "residual": result.residual,
            "seconds": result.seconds, **extra}


def format_report(report: FemReport) -> str:
    """A short aligned block for the CLI: the two matrices, the reference solves, the stiffest cells."""
    r = report
    lines = [("fem mesh", f"{r.n_cells} tetrahedra, {r.n_points} nodes ({r.n_boundary_nodes} on the boundary, "
                          "fixed)")]
    for name, matrix in (("laplace", r.laplace), ("elasticity", r.elasticity))[:2 if r.elasticity else 1]:
        lines += [(f"{name} K", f"cond {matrix.condition:.4g}  lambda min {matrix.lambda_min:.4g}  "
                                f"max {matrix.lambda_max:.4g}  ({matrix.size} dofs, {matrix.seconds:.2f} s)"),
                  (f"{name} D^-1/2 K D^-1/2", f"cond {matrix.jacobi_condition:.4g}  lambda min "
                                              f"{matrix.jacobi_min:.4g}  max {matrix.jacobi_max:.4g}")]
    ref, elastic = r.reference, r.elasticity_solve
    lines.append(("-laplace u = 1, u|bd = 0", f"cg+jacobi {ref['iterations']} iterations, residual "
                                              f"{ref['residual']:.1e}, {ref['seconds']:.2f} s, "
                                              f"max u {ref['max_u']:.4g}"))
    if elastic:
        lines.append(("elasticity, body force", f"cg+jacobi {elastic['iterations']} iterations, residual "
                                                f"{elastic['residual']:.1e}, {elastic['seconds']:.2f} s"))
    width = max(len(label) for label, _ in lines)
    text = [f"{label:<{width}}  {value}" for label, value in lines]
    if r.stiff_cells:
        text.append("stiffest cells (share of laplace lambda max; cell ids of the file):")
        text += [f"  cell {c.index:<8d} {100 * c.share:5.1f}%  Q {c.radius_ratio:.3f}  min dihedral "
                 f"{c.min_dihedral:5.2f} deg  element cond {c.element_condition:.3g}" for c in r.stiff_cells]
    return "\n".join(text)
