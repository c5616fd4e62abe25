"""``bitemesh fem MESH``: the solver check of a tetrahedral mesh (conditioning of P1 -laplace and linear
elasticity, the cells that dominate it, a reference solve)."""
from __future__ import annotations

from ..core.errors import InvalidInputError
from ..core.fem.check import FemParameters, fem_check
from ..io import read_mesh
from .options import add_parameter_options, parameters_from_args


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser("fem", help="check a mesh as a finite-element solver sees it",
                                    description="Assemble P1 -laplace and isotropic linear elasticity on a "
                                                ".vtu/.vtk/.msh/.inp/.mesh tetrahedral mesh with its boundary fixed, "
                                                "print the extreme eigenvalues and condition numbers of the "
                                                "stiffness matrices (plain and Jacobi-scaled, as CG sees them), the "
                                                "cells that dominate the largest eigenvalue (cell ids of the file) "
                                                "and the CG solve of -laplace u = 1, u = 0 on the boundary.")
    parser.add_argument("mesh", help="the tetrahedral mesh to check")
    add_parameter_options(parser, (FemParameters,))
    parser.set_defaults(run=run)


def run(args) -> None:
    print(check(args.mesh, parameters_from_args(args, (FemParameters,))[0], read_mesh(args.mesh)))


def check(path, parameters: FemParameters, mesh):
    """The :class:`~bitemesh.core.fem.check.FemReport` of ``mesh`` read from ``path``; a refusal names the file."""
    if mesh.dim != 3:
        raise InvalidInputError(f"{path}: the solver check needs tetrahedra, and this file holds triangles (a 2D "
                                "mesh); give it a volume mesh (bitemesh mesh ... -o mesh.vtu)")
    try:
        return fem_check(mesh, parameters)
    except InvalidInputError as error:
        raise InvalidInputError(f"{path}: {error}") from None
