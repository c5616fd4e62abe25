"""``bitemesh demo``: the paper's synthetic die (Figure 4), sampled as noisy scattered points, meshed."""
from __future__ import annotations

from ..core.parameters import BitingParameters, ImplicitParameters
from ..core.pipeline import run as run_pipeline
from ..core.quality import quality_summary
from ..core.shapes import die, sample_surface
from ..io import write_mesh
from .mesh import add_optimize_options, optimize_parameters
from .options import ProgressBar, check_output, print_timings


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser("demo", help="mesh the built-in demo (the paper's die)",
                                    description="Sample the die of the paper's Figure 4 (a rounded cube with "
                                                "spherical pips) as noisy scattered points and mesh it.")
    parser.add_argument("-o", "--output", default="die.vtu", help="the mesh to write; default die.vtu")
    parser.add_argument("--cells", type=int, default=10000, help="cells to aim for; default 10000")
    add_optimize_options(parser)
    parser.set_defaults(run=run)


def run(args) -> None:
    check_output(args.output)
    shape = die()
    points, normals = sample_surface(shape, spacing=0.04, noise=0.002, seed=1)
    print(f"die: {len(points)} scattered points with normals, noise sd 0.002 (die size 2)")
    bar = ProgressBar()
    try:
        result = run_pipeline(points, normals, ImplicitParameters(), BitingParameters(cells=args.cells),
                              progress=bar, optimize=optimize_parameters(args))
    finally:
        bar.close()
    write_mesh(result.mesh, args.output)
    volume_error = result.mesh.cell_data["Volume"].sum() / shape.measure - 1
    print(f"wrote {args.output} (radius R = {result.radius:.4g}, volume {volume_error:+.2%} of the exact die)")
    print(quality_summary(result.mesh))
    print("time per step:")
    print_timings(result.seconds)
