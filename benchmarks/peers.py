#!/usr/bin/env python
"""bitemesh (its default, and --no-optimize) beside gmsh and TetGen, side by side in one run (issues #5, #12).

Cases: sphere, torus, die and two-cavity heart (``bitemesh.core.shapes``) at about 10,000 tets; the heart, the die
and the sphere at about 136,000; the sphere at about 1,000,000, and at 10,000,000 by bitemesh alone.  Each mesher x
case runs in its own process (``peers_meshers.py``), which reports its times and its peak memory and saves its
first mesh:

* bitemesh: noisy scattered surface points with normals (``shape_worker.make_input``, seed 0), then the whole
  ``pipeline.run`` with ``BitingParameters(cells=N)``: "default" is ``OptimizeParameters()`` (whatever the dataclass
  says at the commit measured, shown in the row), "--no-optimize" is ``OptimizeParameters(optimize=0)``.
* gmsh (Python API): the exact CAD shape from OpenCASCADE (``peers_cad``), Delaunay, ``Mesh.Optimize = 1``,
  ``Mesh.OptimizeNetgen = 1``, one thread; uniform size calibrated for about N tets by untimed runs.
* TetGen (the ``tetgen`` package): ``-pq1.2a<vol>`` of a surface triangulation made here (``peers_surfaces``) at an
  edge matched to the volume mesh, calibrated the same way; the time is ``tetrahedralize`` only.

Every mesh is measured in this process with bitemesh's own functions (``quality_summary``, ``check_valid_domain``;
volume error against the exact volume).  Cells of gmsh/TetGen with negative signed volume are reoriented (counted)
and unused nodes dropped first, since ``check_valid_domain`` expects positive cells and no unused points.

    /work/bench-venv/bin/python benchmarks/peers.py --output benchmarks/peers.md   # the full table
    /work/bench-venv/bin/python benchmarks/peers.py --quick                        # every case at a small size
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
for p in (str(HERE.parent / "filters"), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

from bitemesh.core import shapes  # noqa: E402
from bitemesh.core.mesh.simplicial import Mesh  # noqa: E402
from bitemesh.core.mesh.validity import check_valid_domain  # noqa: E402
from bitemesh.core.mesh.quality import quality_summary  # noqa: E402
from golden import processor  # noqa: E402
from peers_meshers import MESHERS, ONE_RUN_CELLS, SINGLE_RUN_LIMIT  # noqa: E402
from shape_worker import SHAPES  # noqa: E402

#: the sizes of the cases, full and --quick
SIZES = {"10k": 10_000, "136k": 136_000, "1M": 1_000_000, "10M": 10_000_000}
QUICK = {"10k": 2_000, "136k": 8_000, "1M": 60_000, "10M": 120_000}
CASES = [("sphere", "10k"), ("torus", "10k"), ("die", "10k"), ("two-cavity-heart", "10k"),
         ("two-cavity-heart", "136k"), ("die", "136k"), ("sphere", "136k"), ("sphere", "1M"), ("sphere", "10M")]
#: the sizes that bitemesh meshes alone (issue #12: "10M for bitemesh alone")
ALONE = {"10M"}
#: issue #12's targets: (shape, size, mesher, against, at most): a time ratio against a peer, or peak memory (MiB)
TARGETS = [("two-cavity-heart", "136k", "bitemesh", "tetgen", 2.0),
           ("two-cavity-heart", "136k", "bitemesh", "gmsh", 0.5),
           ("two-cavity-heart", "136k", "bitemesh-no-optimize", "tetgen", 1.0),
           ("sphere", "136k", "bitemesh-no-optimize", "tetgen", 1.0),
           ("sphere", "1M", "bitemesh-no-optimize", "tetgen", 1.0),
           ("sphere", "1M", "bitemesh", "tetgen", 2.0),
           ("sphere", "1M", "bitemesh", "memory", 1024.0)]
WORKER_TIMEOUT = 3 * 3600


# --- measuring -------------------------------------------------------------------------------------------------------

def measure(points, cells, shape) -> dict:
    """bitemesh's metrics of a tet mesh; negative cells are reoriented (counted) and unused nodes dropped."""
    points = np.asarray(points, float)
    cells = np.asarray(cells, np.int64).copy()
    used = np.unique(cells)
    remap = np.full(len(points), -1, np.int64)
    remap[used] = np.arange(used.size)
    unused = len(points) - used.size
    points, cells = points[used], remap[cells]
    a, b, c, d = (points[cells[:, i]] for i in range(4))
    signed = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)
    negative = signed < 0
    cells[negative] = cells[negative][:, [1, 0, 2, 3]]
    mesh = Mesh(points, cells)
    s = quality_summary(mesh)
    problems = check_valid_domain(mesh)
    return dict(cells=s.n_cells, points=s.n_points, q_mean=s.q_mean, q_min=s.q_min,
                angle_min=s.angle_min, percent_q_below_0_3=s.percent_q_below_0_3, edge_cv=s.edge_cv,
                volume_error_percent=100.0 * (s.total_volume - shape.measure) / shape.measure,
                valid=not problems, problems=problems[:3], reoriented=int(negative.sum()), unused_dropped=int(unused))


def run_case(mesher: str, name: str, cells: int, repeat: int) -> dict:
    """One mesher x case in its own process; its record with the metrics of its first mesh."""
    with tempfile.TemporaryDirectory(prefix="peers-") as out:
        command = [sys.executable, str(HERE / "peers_meshers.py"), mesher, name, str(cells), "--repeat", str(repeat),
                   "--out", out]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=WORKER_TIMEOUT)
        except subprocess.TimeoutExpired:
            return dict(ok=False, error=f"no answer in {WORKER_TIMEOUT} s")
        path = Path(out) / "record.json"
        if not path.exists():
            return dict(ok=False, error=f"the worker died (exit status {done.returncode}): {done.stderr[-300:]}")
        record = json.loads(path.read_text())
        if record["ok"]:
            with np.load(Path(out) / "mesh.npz") as mesh:
                record["metrics"] = measure(mesh["points"], mesh["cells"], getattr(shapes, SHAPES[name])())
        return record


# --- the report ------------------------------------------------------------------------------------------------------

def versions() -> dict:
    out = {"python": platform.python_version(), "numpy": np.__version__}
    import scipy
    out["scipy"] = scipy.__version__
    for module in ("gmsh", "tetgen"):
        try:
            out[module] = __import__(module).__version__
        except Exception as error:  # noqa: BLE001
            out[module] = f"not available ({type(error).__name__}: {error})"
    try:
        out["bitemesh"] = subprocess.run(["git", "-C", str(HERE.parent), "describe", "--always", "--dirty"],
                                         capture_output=True, text=True, check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        out["bitemesh"] = "?"
    return out


def memory_total_mb() -> float:
    """This machine's memory, MiB (/proc/meminfo)."""
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def machine() -> str:
    return (f"{platform.system()} {platform.release()} {platform.machine()}, {processor()}, "
            f"{os.cpu_count()} logical CPUs, {memory_total_mb() / 1024:.1f} GiB")


def label(mesher: str, record: dict) -> str:
    if mesher == "bitemesh":
        return f"bitemesh default (optimize={record['optimize']})" if "optimize" in record else "bitemesh default"
    return {"bitemesh-no-optimize": "bitemesh --no-optimize", "gmsh": "gmsh Delaunay + Netgen opt.",
            "tetgen": "TetGen -pq1.2a"}[mesher]


COLUMNS = [("mesher", "{}"), ("tets", "{:,}"), ("nodes", "{:,}"), ("mean Q", "{:.3f}"), ("min Q", "{:.3f}"),
           ("min dihedral (deg)", "{:.1f}"), ("% Q < 0.3", "{:.2f}"), ("edge CV", "{:.3f}"),
           ("volume error %", "{:+.2f}"), ("valid", "{}"), ("runs", "{}"), ("seconds (median)", "{:.2f}"),
           ("x bitemesh time", "{:.2f}"), ("x TetGen time", "{:.2f}"), ("x gmsh time", "{:.2f}"),
           ("peak MB", "{:,.0f}")]


def table(records: dict) -> list:
    """Markdown rows of one case; records: mesher -> record (ok ones only)."""
    median = {m: float(np.median(r["seconds"])) for m, r in records.items()}
    ratio = lambda m, base: median[m] / median[base] if base in median else float("nan")  # noqa: E731
    lines = ["| " + " | ".join(c for c, _ in COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for mesher, r in records.items():
        m = r["metrics"]
        row = [label(mesher, r), m["cells"], m["points"], m["q_mean"], m["q_min"], m["angle_min"],
               m["percent_q_below_0_3"], m["edge_cv"], m["volume_error_percent"], "yes" if m["valid"] else "NO",
               len(r["seconds"]), median[mesher], ratio(mesher, "bitemesh"), ratio(mesher, "tetgen"),
               ratio(mesher, "gmsh"), r["peak_mb"]]
        cells = ["-" if isinstance(v, float) and np.isnan(v) else fmt.format(v) for (_, fmt), v in zip(COLUMNS, row)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def note(name: str, cells: int, mesher: str, r: dict) -> str:
    if not r["ok"]:
        return f"- {name} ~{cells:,}, {label(mesher, r)}: failed: {r['error']}"
    m, extra = r["metrics"], []
    if m["reoriented"]:
        extra.append(f"{m['reoriented']} cells reoriented")
    if m["unused_dropped"]:
        extra.append(f"{m['unused_dropped']} unused nodes dropped")
    if m["problems"]:
        extra.append("problems: " + "; ".join(m["problems"]))
    times = ", ".join(f"{s:.2f}" for s in r["seconds"])
    cpu = ", ".join(f"{s:.2f}" for s in r["cpu_seconds"])
    text = f"- {name} ~{cells:,}, {label(mesher, r)}: {r['note']}; seconds {times} (CPU {cpu})"
    if "steps" in r:
        text += "; first run's steps (s): " + ", ".join(f"{k} {v}" for k, v in r["steps"].items())
    if r.get("warnings"):
        text += "; warnings: " + " / ".join(r["warnings"])
    return text + (" (" + ", ".join(extra) + ")" if extra else "")


def targets(results: dict) -> list:
    """The "Targets" section: each target, its measured value and met / missed by how much."""
    lines = ["## Targets (issue #12)", "", "Time ratios of the wall-clock medians above (in brackets: of the CPU "
             "seconds, steadier on this shared machine).", "",
             "| case | target | measured | verdict |", "|---|---|---|---|"]
    for name, size, mesher, against, limit in TARGETS:
        records = results.get((name, size), {})
        who = (f"{name} ~{records.get('cells', 0):,}, "
               + ("bitemesh default" if mesher == "bitemesh" else "bitemesh --no-optimize"))
        if mesher not in records or (against != "memory" and against not in records):
            lines.append(f"| {who} | {'peak memory' if against == 'memory' else against} | not measured | - |")
            continue
        r = records[mesher]
        if against == "memory":
            value, goal = r["peak_mb"], f"peak memory <= {limit:,.0f} MiB"
            shown, over = f"{value:,.0f} MiB", f", {value - limit:,.0f} MiB over"
        else:
            value = float(np.median(r["seconds"]) / np.median(records[against]["seconds"]))
            cpu = float(np.median(r["cpu_seconds"]) / np.median(records[against]["cpu_seconds"]))
            goal, shown, over = f"time <= {limit:g}x {label(against, {})}", f"{value:.2f}x ({cpu:.2f}x)", ""
        verdict = (f"met ({value / limit:.2f} of the bound)" if value <= limit
                   else f"missed by a factor {value / limit:.2f}{over}")
        lines.append(f"| {who} | {goal} | {shown} | {verdict} |")
    return lines + [""]


def ten_million(results: dict, cells: int) -> list:
    """The 10M-cell sphere (bitemesh alone): measured, or estimated from its run at ``cells`` (grid nodes and peak
    memory scale with the cell count, the grid spacing being R / 4) when it was not run."""
    lines = ["## 10,000,000 cells (bitemesh alone)", ""]
    measured = results.get(("sphere", "10M"), {})
    for mesher in ("bitemesh-no-optimize", "bitemesh"):
        r = measured.get(mesher)
        if r:
            m = r["metrics"]
            lines.append(f"- {label(mesher, r)}: completed in {np.median(r['seconds']):,.0f} s, {m['cells']:,} tets, "
                         f"grid of {r['grid_nodes']:,} nodes, peak {r['peak_mb']:,.0f} MiB of this machine's "
                         f"{memory_total_mb():,.0f}; mean Q {m['q_mean']:.3f}, min dihedral {m['angle_min']:.1f} deg, "
                         f"valid: {'yes' if m['valid'] else 'NO'}.")
    r = results.get(("sphere", "1M"), {}).get("bitemesh")
    if len(lines) == 2 and r:
        factor = 10_000_000 / cells
        lines.append(f"Not run; estimated from the sphere at {cells:,} (default, grid of {r['grid_nodes']:,} nodes, "
                     f"peak {r['peak_mb']:,.0f} MiB): ~{factor * r['peak_mb']:,.0f} MiB against this machine's "
                     f"{memory_total_mb():,.0f} MiB.")
    return lines + [""]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="every case at a small size: "
                        + ", ".join(f"{SIZES[k]:,} -> {v:,}" for k, v in QUICK.items()))
    parser.add_argument("--cases", nargs="+", metavar="SHAPE:SIZE", help="instead of the table's cases, e.g. "
                        "sphere:10k die:2000 (sizes: a number or 10k, 136k, 1M)")
    parser.add_argument("--meshers", nargs="+", default=list(MESHERS), choices=MESHERS)
    parser.add_argument("--alone-meshers", nargs="+", default=["bitemesh-no-optimize", "bitemesh"],
                        choices=MESHERS[:2], help="the meshers of the sizes bitemesh meshes alone (10M)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per mesher and case (median)")
    parser.add_argument("--output", type=Path)
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else SIZES
    cases = [tuple(c.split(":")) for c in args.cases] if args.cases else CASES
    info = versions()
    lines = ["# bitemesh beside gmsh and TetGen", "",
             f"Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M UTC}  ",
             f"Machine: {machine()}  ",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in info.items()) + "  ",
             f"Command: `{Path(sys.executable).name} benchmarks/peers.py "
             + " ".join(argv if argv is not None else sys.argv[1:]) + "`", ""]
    results, notes = {}, []
    for name, size in cases:
        cells = sizes[size] if size in sizes else int(size)
        records = {}
        for mesher in args.alone_meshers if size in ALONE else args.meshers:
            r = run_case(mesher, name, cells, args.repeat)
            notes.append(note(name, cells, mesher, r))
            print(notes[-1], flush=True)
            if r["ok"]:
                records[mesher] = r
        results[name, size] = dict(records, cells=cells)
        lines += [f"## {name}, ~{cells:,} tets (exact volume {getattr(shapes, SHAPES[name])().measure:.5f})", ""]
        lines += table(records) + [""]
    lines += [f"Seconds: the median of up to {args.repeat} runs in the worker process (one run for "
              f"{ONE_RUN_CELLS:,} tets and above, or when one run took over {SINGLE_RUN_LIMIT:.0f} s; 'runs' says "
              "how many). bitemesh: the whole pipeline.run from scattered points (implicit fit, optimizer, quality "
              "and fidelity included); gmsh: generate(3) from the exact CAD shape, one thread "
              "(General.NumThreads = 1); TetGen: tetrahedralize of a given surface triangulation (building the "
              "surface untimed); calibration runs untimed. x bitemesh / TetGen / gmsh time: this row's median over "
              "that mesher's, same case.", "",
              "Peak MB: the worker process's peak resident set (VmHWM, MiB) at its end, nothing subtracted (not "
              "ru_maxrss, which execve keeps from the parent's RSS at the fork): the interpreter and "
              "imports (numpy, scipy, bitemesh; gmsh's or TetGen's library), the input (bitemesh: making the "
              "scattered points; TetGen: the surface), the calibration runs and every timed run; measuring the "
              "mesh happens in the parent, outside it.", ""]
    if not args.cases:
        lines += targets(results) + ten_million(results, sizes["1M"])
    lines += ["Notes per mesh:", ""] + notes + [""]
    text = "\n".join(lines)
    print(text)
    if args.output:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
