"""``bitemesh quality MESH``: the quality summary of a mesh, and optionally its radius-ratio histogram."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.mesh.betti import mesh_topology
from ..core.errors import InvalidInputError, MeshingError, point_text
from ..core.fem.check import FemParameters
from ..core.parameters import OptimizeParameters, QualityParameters
from ..core.mesh.validity import check_valid_domain
from ..core.mesh.quality import quality_histogram, quality_summary, radius_ratio
from ..core.optimize.measures import smallest_angles
from ..core.optimize.slivers import poor_cells
from ..io import atomic_output, read_mesh
from .fem import check
from .options import add_parameter_options, parameters_from_args


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser("quality", help="print the quality of a mesh",
                                    description="Radius ratio Q = 3 r_in / R_circ (1 is regular), angles, volume "
                                                "and edge lengths of a .vtu/.vtk/.msh/.inp/.mesh mesh, and its "
                                                "defects as a finite-element domain (inverted, flat or duplicated "
                                                "cells, unused points, a boundary that is not a closed manifold): "
                                                "exit code 1 when it has any.")
    parser.add_argument("mesh", help="the mesh to measure")
    parser.add_argument("--histogram", metavar="OUT.png", help="also draw the radius-ratio histogram (matplotlib)")
    parser.add_argument("--fem", action="store_true", help="also the solver check of bitemesh fem (conditioning of "
                                                           "P1 -laplace and elasticity, stiffest cells, a CG solve), "
                                                           "for a valid domain")
    add_parameter_options(parser, (QualityParameters, FemParameters))
    parser.set_defaults(run=run)


def run(args) -> None:
    mesh = read_mesh(args.mesh, orient=False)   # as the file has it: inverted cells are defects to report
    print(quality_summary(mesh))
    if args.histogram:
        bins = parameters_from_args(args, (QualityParameters,))[0].bins
        save_histogram(radius_ratio(mesh.points, mesh.cells), args.histogram, bins, title=args.mesh)
        print(f"wrote {args.histogram}")
    problems = check_valid_domain(mesh)
    if problems:
        print("defects:")
        for problem in problems:
            print(f"  {problem}")
        raise MeshingError(f"{args.mesh} is not a valid finite-element domain: {len(problems)} kinds of defect "
                           f"({problems[0]}{', ...' if len(problems) > 1 else ''})")
    print("defects: none (a valid domain: no inverted, zero-volume or duplicated cell, a closed manifold boundary)")
    print(poor_cells_line(mesh))
    print(f"topology: {mesh_topology(mesh).describe()} (handles: tunnels through it, or holes in 2D; voids: "
          "closed cavities inside it)")
    if args.fem:
        print(check(args.mesh, parameters_from_args(args, (FemParameters,))[0], mesh))


def poor_cells_line(mesh) -> str:
    """How many cells lie below the optimizer's default bounds (slivers: valid, but they stiffen a solve), the
    worst and where."""
    bounds = OptimizeParameters()
    bound = f"a {'dihedral' if mesh.dim == 3 else 'interior'} angle below {bounds.min_dihedral:g} degrees or a " \
        f"radius ratio below {bounds.min_quality:g}"
    poor = poor_cells(mesh.points, mesh.cells, bounds.min_dihedral, bounds.min_quality)
    if not len(poor):
        return f"poor cells: none ({bound}: the optimizer's bounds)"
    angles = smallest_angles(mesh.points, mesh.cells[poor])
    worst = mesh.points[mesh.cells[poor[int(np.argmin(angles))]]].mean(axis=0)
    return (f"poor cells: {len(poor)} with {bound} (the optimizer's bounds), the worst {angles.min():.2f} degrees at "
            f"{point_text(worst)}: slivers stiffen a finite-element solve (--fem "
            "measures how much)")


def save_histogram(q, path: str, bins: int, title: str) -> None:
    """Draw the radius-ratio histogram like the paper's Figure 5 into a PNG."""
    counts, edges = quality_histogram(q, bins)
    try:
        import matplotlib
        matplotlib.use("Agg")
        from matplotlib import pyplot
    except ImportError:
        raise InvalidInputError("--histogram needs matplotlib: pip install 'bitemesh[plot]'") from None
    figure, axes = pyplot.subplots(figsize=(6, 4))
    axes.bar(edges[:-1], counts, width=edges[1] - edges[0], align="edge", edgecolor="black")
    axes.set(xlabel="radius ratio Q = 3 r_in / R_circ", ylabel="cells", xlim=(0, 1),
             title=f"{title}: mean Q {q.mean():.3f}, std {q.std():.3f}")
    figure.tight_layout()
    try:
        with atomic_output(path, "the histogram") as temporary:
            figure.savefig(temporary, dpi=100, format=Path(path).suffix.lstrip(".").lower() or "png")
    except ValueError as error:  # an image format matplotlib cannot write
        raise InvalidInputError(f"--histogram {path}: {error}") from None
    finally:
        pyplot.close(figure)
