"""``bitemesh fit TEMPLATE DATA [DATA ...] -o OUTPUT``: the elastic template moved onto new data, the same cells;
several DATA are the frames of a cycle, written as a ParaView time series with the cavity volumes."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import InvalidInputError
from ..core.fem.template import FitParameters
from ..fitting import fit, fit_cycle, frame_fit_row
from ..io import write_time_series
from ..meshing import check_output, write
from .options import ProgressBar, add_parameter_options, add_threads_option, parameters_from_args


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser(
        "fit", help="deform a tagged mesh (the template) onto new data, keeping its cells",
        description="Move a bitemesh mesh onto new data with the same cells (the paper's deformable elastic "
                    "template): each tagged surface is pulled to the data that samples it (a biv-me GPFile: EPI to "
                    "the epicardial contours, LV_ENDO and RV_ENDO to the endocardial, BASE to the valve points; "
                    "scattered points or a label map: the whole boundary), the template's elasticity carries the "
                    "rest and the fibres follow. Several DATA are the frames of a cycle, each fitted from the last: "
                    "OUTPUT is then a .pvd time series (one .vtu a frame beside it) and the LV / RV cavity volumes, "
                    "end-diastole, end-systole and the ejection fraction are printed.")
    parser.add_argument("template", help="the mesh to deform (a bitemesh .vtu with its tags, e.g. from bitemesh mesh)")
    parser.add_argument("data", nargs="+", help="the data to fit: one file, or one a frame in the cycle's order")
    parser.add_argument("-o", "--output", required=True, help="the fitted mesh (.vtu, .xdmf, ...), or the .pvd "
                                                              "time series for several frames")
    parser.add_argument("--frame", type=float, help="the frame of a GPFile that holds several (one DATA)")
    add_parameter_options(parser, (FitParameters,))
    add_threads_option(parser)
    parser.set_defaults(run=run)


def run(args) -> None:
    pull = parameters_from_args(args, (FitParameters,))[0].pull
    if len(args.data) == 1:
        check_output(args.output)
        bar = ProgressBar()
        try:
            fitted = fit(args.template, args.data[0], frame=args.frame, pull=pull, progress=bar)
        finally:
            bar.close()
        write(fitted, args.output)
        print(f"wrote {args.output}: {fit_summary(frame_fit_row(fitted))}")
        return
    output = Path(args.output)
    if output.suffix.lower() != ".pvd":
        raise InvalidInputError(f"-o {args.output}: several DATA make a time series; name a .pvd file (each frame "
                                f"is written beside it as {output.stem}_NNN.vtu)")
    if args.frame is not None:
        raise InvalidInputError("--frame picks a frame of one GPFile; with several DATA leave it out")
    check_output(output.with_suffix(".vtu"))
    bar = ProgressBar()
    try:
        cycle = fit_cycle(args.template, args.data, pull=pull, progress=bar)
    finally:
        bar.close()
    write_time_series(output, [fitted.mesh for fitted in cycle.fits])
    for number, (fitted, volumes) in enumerate(zip(cycle.fits, cycle.volumes)):
        print(f"frame {number}: LV {volumes[0]:.1f} ml, RV {volumes[1]:.1f} ml; {fit_summary(frame_fit_row(fitted))}")
    print(f"end-diastole: frame {cycle.end_diastole} (LV {cycle.volumes[cycle.end_diastole, 0]:.1f} ml), "
          f"end-systole: frame {cycle.end_systole} (LV {cycle.volumes[cycle.end_systole, 0]:.1f} ml), "
          f"ejection fraction {cycle.ejection_fraction:.1f} %")
    print(f"wrote {output} ({len(cycle.fits)} frames)")


def fit_summary(row: dict) -> str:
    return (f"data to the boundary mean {row['data_mean']:.2f}, 95 % {row['data_p95']:.2f}; smallest dihedral "
            f"angle {row['min_dihedral']:.1f} deg, radius ratio {row['min_radius_ratio']:.3f}; {row['rounds']} "
            f"rounds, {row['seconds']:.1f} s")

