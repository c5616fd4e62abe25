"""``bitemesh mesh INPUT -o OUTPUT``: scattered points, or a label map, to a tetrahedral mesh."""
from __future__ import annotations

from dataclasses import fields
from pathlib import Path

from ..core.errors import InvalidInputError
from ..core.fem.coordinates import CoordinateParameters
from ..core.mesh.simplicial import signed_measures
from ..core.parameters import LabelledParameters, LabelMapParameters, TableParameters
from ..core.sources.spacetime import SpaceTimeParameters
from ..io import mesh_files, remove_stale_partials, write_time_series
from ..meshing import check_output, instants, mesh
from ..options import OPTION_NAMES, Options
from .options import (ProgressBar, add_fibre_options, add_parameter_options, add_threads_option, describe,
                      write_and_report)


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser(
        "mesh", help="mesh scattered points, labelled contours or a label map",
        description="Mesh the shape sampled by scattered points: .xyz/.csv/.txt (x y z [nx ny nz]) or "
                    ".vtp/.vtk/.vtu/.ply/.obj/.stl (points, and normals where present; a volume mesh's boundary); "
                    "or labelled contour points (a biv-me GPFile, a table with a label column, a VTP with a Label "
                    "array), meshed as the domain their surfaces bound (--domain); or the labels of a label map "
                    "(.nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd, meshed in its physical LPS space). Writes .vtu/.vtk, "
                    ".msh (gmsh), .xdmf (XDMF + HDF5, for dolfinx), .inp (Abaqus), .mesh (MEDIT) or .pts (openCARP, "
                    "with .elem, .lon and a .surf and .vtx a surface). --fibres adds the myocardial fibres of a "
                    "biventricular heart (labelled contours) as cell vectors (.vtu/.vtk/.xdmf; .pts: Fibre and "
                    "Sheet).")
    parser.add_argument("input", nargs="+", help="the scattered points, labelled contours or a label map; with "
                                                 "--space-time, the frames of one cycle in its order")
    parser.add_argument("-o", "--output", required=True, help="the mesh to write")
    add_mesh_options(parser)
    add_parameter_options(parser, (SpaceTimeParameters,))
    parser.set_defaults(run=run)


def add_mesh_options(parser) -> None:
    """The options of one mesh (``bitemesh mesh``, and each case of ``bitemesh batch``), from the dataclasses."""
    add_parameter_options(parser, (TableParameters,))
    add_parameter_options(parser)
    add_parameter_options(parser, (LabelledParameters,))
    unit = {item.name: item for item in fields(Options)}["unit"]
    parser.add_argument("--unit", choices=unit.metadata["choices"], default=unit.default,
                        help=describe(unit.metadata, unit.default))
    parser.add_argument("--config", metavar="FILE", help="labelled contours: a JSON or TOML file with the domain and "
                                                         "its options (flags given on the command line win)")
    labels = parser.add_argument_group("label maps")
    label = {item.name: item for item in fields(LabelMapParameters)}["label"]
    labels.add_argument("--label", type=int, action="append", metavar="N",
                        help=describe(label.metadata, None) + " (repeat for a union)")
    labels.add_argument("--ras", action="store_true", help="write the mesh in RAS (3D Slicer) instead of LPS (ITK)")
    add_fibre_options(parser)
    add_parameter_options(parser, (CoordinateParameters,))
    add_threads_option(parser)


def options_of(args) -> Options:
    """The Options of parsed ``bitemesh mesh`` flags (checked by the step dataclasses); --radius and --cells
    together are refused (radius would set the size alone, and a flag given is not dropped silently)."""
    if args.radius is not None and args.cells is not None:
        raise InvalidInputError(f"--radius {args.radius:g} and --cells {args.cells} both set the size of the cells "
                                "(radius would win); give one of them")
    return Options(**{name: getattr(args, name) for name in OPTION_NAMES if hasattr(args, name)})


def run(args) -> None:
    options = options_of(args)
    if len(args.input) > 1 and not options.space_time:
        raise InvalidInputError(f"{len(args.input)} inputs given ({args.input[0]}, {args.input[1]}, ...): bitemesh "
                                "mesh meshes one; add --space-time to mesh them as the frames of one cycle, or use "
                                "bitemesh batch to mesh each")
    check_output(args.output, options)
    for path in mesh_files(args.output):   # what a killed run left, whether this run writes or is refused
        remove_stale_partials(path)
    bar = ProgressBar()
    try:
        result = mesh(args.input if options.space_time else args.input[0], options, progress=bar)
    finally:
        bar.close()
    write_and_report(result, args.output)
    if options.space_time:
        series = Path(args.output).with_suffix(".pvd")
        sections = instants(result)
        write_time_series(series, sections)
        volumes = ", ".join(f"{signed_measures(section.points, section.cells).sum():.4g}" for section in sections)
        print(f"wrote {series}: each frame's instant ({series.stem}_000.vtu ...), volumes {volumes}")
