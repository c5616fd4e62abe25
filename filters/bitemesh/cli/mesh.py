"""``bitemesh mesh INPUT -o OUTPUT``: scattered points, or a label map, to a tetrahedral mesh."""
from __future__ import annotations

from dataclasses import fields

from ..core.errors import InvalidInputError
from ..core.parameters import LabelledParameters, LabelMapParameters, TableParameters
from ..core.pipeline import run as run_pipeline
from ..io import looks_labelled, read_labelled_config, read_labelled_points, read_points
from ..labelmap import LABEL_MAP_EXTENSIONS
from .options import (ProgressBar, add_parameter_options, check_output, describe, parameters_from_args,
                      write_and_report)


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser(
        "mesh", help="mesh scattered points, labelled contours or a label map",
        description="Mesh the shape sampled by scattered points: .xyz/.csv/.txt (x y z [nx ny nz]) or "
                    ".vtp/.vtk/.vtu/.ply/.obj/.stl (points, and normals where present; a volume mesh's boundary); "
                    "or labelled contour points (a biv-me GPFile, a table with a label column, a VTP with a Label "
                    "array), meshed as the domain their surfaces bound (--domain); or the labels of a label map "
                    "(.nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd, meshed in its physical LPS space). Writes .vtu/.vtk, .msh "
                    "(gmsh), .inp (Abaqus) or .mesh (MEDIT).")
    parser.add_argument("input", help="the scattered points, or a label map")
    parser.add_argument("-o", "--output", required=True, help="the mesh to write")
    add_parameter_options(parser, (TableParameters,))
    add_parameter_options(parser)
    add_parameter_options(parser, (LabelledParameters,))
    parser.add_argument("--config", metavar="FILE", help="labelled contours: a JSON or TOML file with the domain and "
                                                         "its options (flags given on the command line win)")
    labels = parser.add_argument_group("label maps")
    label = {item.name: item for item in fields(LabelMapParameters)}["label"]
    labels.add_argument("--label", type=int, action="append", metavar="N",
                        help=describe(label.metadata, None) + " (repeat for a union)")
    labels.add_argument("--ras", action="store_true", help="write the mesh in RAS (3D Slicer) instead of LPS (ITK)")
    parser.set_defaults(run=run)


def run(args) -> None:
    check_output(args.output)
    table = parameters_from_args(args, (TableParameters,))[0]
    columns = table.columns or None
    label_map = args.input.lower().endswith(LABEL_MAP_EXTENSIONS)
    labelled = not label_map and (looks_labelled(args.input) or (columns and "label" in columns.lower()))
    given = [flag for flag, on in (("--config", args.config), ("--frame", table.frame is not None),
                                   *((f"--{name.replace('_', '-')}", True) for name in labelled_flags(args))) if on]
    if given and not labelled:
        raise InvalidInputError(
            f"{given[0]} applies to labelled contours, and '{args.input}' has no label column or Label array (a "
            "biv-me GPFile, a table whose header names a label column, a VTP with a Label point array); leave "
            f"{given[0]} out to mesh the points as one surface")
    if columns and label_map:
        raise InvalidInputError(f"--columns applies to text tables, not to the label map '{args.input}'")
    implicit, biting, spurious, optimize, fidelity = parameters_from_args(args)
    steps = {"implicit": implicit, "biting": biting, "spurious": spurious, "optimize": optimize,
             "fidelity": fidelity}
    bar = ProgressBar()
    try:
        if label_map:
            result = mesh_label_map(args, steps, bar)
        elif labelled:
            result = mesh_labelled_points(args, steps, bar, columns=columns, frame=table.frame)
        else:
            result = run_pipeline(*read_points(args.input, columns), progress=bar, **steps)
    finally:
        bar.close()
    write_and_report(result, args.output)


def mesh_label_map(args, steps: dict, progress):
    from ..labelmap import mesh_label_grid, read_label_map
    label_map = read_label_map(args.input)
    return mesh_label_grid(label_map.labels, label_map.index_to_physical(ras=args.ras),
                           labels={LabelMapParameters(label=label).label for label in args.label} if args.label
                           else None, progress=progress, **steps)


def labelled_flags(args) -> dict:
    """The labelled-contour flags given on the command line (those not at their default), as keywords of
    run_labelled."""
    from ..core.contours.run import labelled_keywords
    return labelled_keywords(parameters_from_args(args, (LabelledParameters,))[0], given_only=True)


def mesh_labelled_points(args, steps: dict, progress, path=None, columns=None, frame=None):
    """Labelled contour points (``path``, default the input; time frame ``frame``) to the mesh of the domain of
    ``--domain``."""
    from ..core.contours.run import run_labelled
    points, labels, slices = read_labelled_points(path or args.input, columns=columns, frame=frame)
    options = read_labelled_config(args.config) if args.config else {}
    options.update(labelled_flags(args))   # a flag given wins over the config file
    return run_labelled(points, labels, slices=slices, progress=progress, **steps, **options)
