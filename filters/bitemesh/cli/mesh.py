"""``bitemesh mesh INPUT -o OUTPUT``: scattered points to a tetrahedral mesh."""
from __future__ import annotations

from ..core.pipeline import run as run_pipeline
from ..core.quality import quality_summary
from ..io import read_points, write_mesh
from .options import ProgressBar, add_parameter_options, check_output, parameters_from_args, print_timings


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser(
        "mesh", help="mesh scattered points",
        description="Mesh the shape sampled by scattered points: .xyz/.csv/.txt (x y z [nx ny nz]) or "
                    ".vtp/.vtk/.ply/.obj/.stl (points, and normals where present). Writes .vtu/.vtk, .msh "
                    "(gmsh), .inp (Abaqus) or .mesh (MEDIT).")
    parser.add_argument("input", help="the scattered points")
    parser.add_argument("-o", "--output", required=True, help="the mesh to write")
    add_parameter_options(parser)
    parser.set_defaults(run=run)


def run(args) -> None:
    check_output(args.output)
    points, normals = read_points(args.input)
    bar = ProgressBar()
    try:
        result = run_pipeline(points, normals, *parameters_from_args(args), progress=bar)
    finally:
        bar.close()
    write_mesh(result.mesh, args.output)
    print(f"wrote {args.output} (radius R = {result.radius:.4g})")
    print(quality_summary(result.mesh))
    print("time per step:")
    print_timings(result.seconds)
