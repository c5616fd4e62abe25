"""``bitemesh demo [die|heart]``: the paper's two examples.

``die``: the synthetic die of the paper's Figure 4, sampled as noisy scattered points (about 10,000 cells).
``heart``: real biventricular cardiac MR guide points (biv-me, Apache-2.0, shipped in the package), meshed as the
two-cavity myocardium at about 136,000 cells like the paper's heart; ``--fibres`` adds its myocardial fibres
(Bayer et al. 2012) as cell vectors.
"""
from __future__ import annotations

from dataclasses import fields
from importlib import resources

from ..core.errors import InvalidInputError
from ..core.fem.fibres import FibreParameters
from ..core.parameters import DEFAULT_CELLS, BitingParameters, OptimizeParameters
from ..core.shapes import die, die_samples
from ..meshing import Samples, check_output, mesh
from ..options import Options
from .options import (ProgressBar, add_fibre_options, add_parameter_options, add_threads_option, describe,
                      write_and_report)

#: cells asked for the heart: the cells-per-volume estimate undershoots by about 12 % on thin walls.
HEART_CELLS = 155000


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser("demo", help="mesh a built-in demo: the paper's die, or a real heart",
                                    description=__doc__.split("\n\n", 1)[1])
    parser.add_argument("dataset", nargs="?", choices=("die", "heart"), default="die",
                        help="die (default) or heart")
    parser.add_argument("-o", "--output", help="the mesh to write; default die.vtu or heart.vtu")
    cells = {item.name: item for item in fields(BitingParameters)}["cells"]
    parser.add_argument("--cells", type=int, help=describe(cells.metadata, None)
                        + f"; default {DEFAULT_CELLS} (die), 136000 (heart)")
    add_parameter_options(parser, (OptimizeParameters,))
    add_fibre_options(parser)
    add_threads_option(parser)
    parser.set_defaults(run=run)


def run(args) -> None:
    if args.cells is not None:
        BitingParameters(cells=args.cells)   # its range, refused naming cells before the heart's scaling
    args.output = args.output or f"{args.dataset}.vtu"
    heart = args.dataset == "heart"
    cells = (round(args.cells * HEART_CELLS / 136000) if args.cells else HEART_CELLS) if heart else args.cells
    options = Options(cells=cells, **{item.name: getattr(args, item.name)
                                      for cls in (OptimizeParameters, FibreParameters) for item in fields(cls)})
    check_output(args.output, options)
    if options.fibres and not heart:
        raise InvalidInputError("--fibres: the die has no myocardium; the heart has: bitemesh demo heart --fibres")
    bar = ProgressBar()
    try:
        result, note = (mesh_heart if heart else mesh_die)(options, bar)
    finally:
        bar.close()
    write_and_report(result, args.output, note)


def mesh_die(options: Options, progress):
    shape = die()
    points, normals = die_samples()
    print(f"die: {len(points)} scattered points with normals, noise sd 0.002 (die size 2)")
    result = mesh(Samples(points, normals), options, progress=progress)
    volume_error = result.mesh.cell_data["Volume"].sum() / shape.measure - 1
    return result, f", volume {volume_error:+.2%} of the exact die"


def mesh_heart(options: Options, progress):
    source = resources.files("bitemesh") / "data" / "bivme_patient1" / "GPFile_000.txt"
    print("heart: guide points on short- and long-axis cardiac MR contours (biv-me patient1, Apache-2.0), mm")
    with resources.as_file(source) as path:
        result = mesh(path, options, progress=progress)
    return result, f", myocardium {result.mesh.cell_data['Volume'].sum() / 1000:.1f} ml"
