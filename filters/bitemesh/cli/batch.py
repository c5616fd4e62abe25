"""``bitemesh batch INPUT... -o OUTDIR``: a cohort, each case meshed as ``bitemesh mesh`` meshes it, one Dask task
per case, with summary.csv and report.html in OUTDIR."""
from __future__ import annotations

import sys

from ..core.errors import MeshingError
from ..core.fem.template import FitParameters
from ..io import MESH_EXTENSIONS
from .mesh import add_mesh_options, options_of
from .options import ProgressBar, add_parameter_options, parameters_from_args


def add_parser(subcommands) -> None:
    parser = subcommands.add_parser(
        "batch", help="mesh many cases (a cohort) on Dask",
        description="Mesh every case as 'bitemesh mesh' would, one Dask task per case: on an embedded cluster of "
                    "this machine's cores (--workers), or on a running Dask scheduler (--scheduler). A case that "
                    "fails is its row of OUTDIR/summary.csv and the others go on; a case whose output and record "
                    "match its input and options is skipped, so that rerunning an interrupted command meshes only "
                    "what is missing. Writes OUTDIR/summary.csv and OUTDIR/report.html. With --template every case "
                    "is that mesh fitted to the case's data as 'bitemesh fit' fits it (one connectivity for the "
                    "cohort), and OUTDIR/shape/ holds the cohort's mean shape and main modes of variation.")
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="files, folders (their point, contour and label map files), glob patterns (quoted), "
                             "or a manifest CSV: a header 'input,output,...', one row per case, any other column "
                             "named like an option below (cells, grid_spacing, ...) for that case")
    parser.add_argument("-o", "--output-dir", required=True, metavar="OUTDIR",
                        help="the folder of the meshes (CASE.vtu), summary.csv and report.html (made if absent)")
    parser.add_argument("--format", default=".vtu", choices=MESH_EXTENSIONS,
                        help="the mesh format of every case whose manifest output has none; default .vtu")
    dask = parser.add_argument_group("Dask")
    dask.add_argument("--workers", type=int, metavar="N",
                      help="worker processes of the embedded cluster, one thread each; default one per core")
    dask.add_argument("--worker-memory", metavar="SIZE",
                      help="each worker's memory limit (e.g. 2GB): a worker over it is restarted and its case run "
                           "again, then failed; default the machine's memory shared among the workers")
    dask.add_argument("--retries", type=int, default=2, metavar="N",
                      help="times a case runs again after its worker died (embedded cluster); default 2")
    dask.add_argument("--scheduler", metavar="ADDRESS",
                      help="a running Dask scheduler (tcp://host:8786, e.g. from dask-jobqueue) to send the cases "
                           "to; default $DASK_SCHEDULER_ADDRESS, else the embedded cluster")
    fitting = parser.add_argument_group("a cohort fitted with one template")
    fitting.add_argument("--template", metavar="MESH",
                         help="a tagged bitemesh mesh (e.g. from bitemesh mesh) fitted to every case instead of "
                              "meshing it: every output has its cells; the mesh options below do not apply")
    add_parameter_options(parser, (FitParameters,))
    add_mesh_options(parser)
    parser.set_defaults(run=run)


def run(args) -> None:
    from ..cohorts.run import batch, dashboard_link

    def connected(client):
        link = dashboard_link(client)
        print(f"Dask: {len(client.scheduler_info().get('workers', {}))} workers"
              + (f", dashboard {link}" if link else ""), flush=True)

    bar = ProgressBar()
    try:
        rows = batch(args.inputs, options_of(args).as_dict(), output_dir=args.output_dir, template=args.template,
                     pull=parameters_from_args(args, (FitParameters,))[0].pull, workers=args.workers,
                     worker_memory=args.worker_memory, retries=args.retries, scheduler=args.scheduler,
                     extension=args.format, progress=bar, on_client=connected)
    except KeyboardInterrupt:
        bar.close()
        print(f"bitemesh: interrupted; the summary of the finished cases is in {args.output_dir}/summary.csv "
              "(run the same command again to mesh the others)", file=sys.stderr)
        raise
    bar.close()
    counts = {status: sum(row["status"] == status for row in rows) for status in ("done", "skipped", "failed")}
    print(f"{len(rows)} cases: " + ", ".join(f"{count} {status}" for status, count in counts.items()))
    for row in rows:
        if row["status"] == "failed":
            print(f"  {row['case']}: {row['message']}")
    print(f"wrote {args.output_dir}/summary.csv and {args.output_dir}/report.html"
          + (f", the shape model in {args.output_dir}/shape/" if args.template else ""))
    if counts["failed"]:
        raise MeshingError(f"{counts['failed']} of {len(rows)} cases failed (their messages are in "
                           f"{args.output_dir}/summary.csv)")
