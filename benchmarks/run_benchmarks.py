#!/usr/bin/env python
"""Reproducible timing and quality benchmark of bitemesh on analytic shapes, beside the paper's plain method.

For each shape and target cell count the shape is sampled as noisy scattered points with outward normals (fixed
seed), and the whole pipeline (``bitemesh.core.sources.points.run``: MPU fit, sampling on the grid I, biting, Delaunay,
spurious cells with validity repair, quality) meshes it.  Every case runs in a fresh Python process, so that its
peak memory is its own; a second fresh process then meshes the *same* grid I with the paper's plain method
(biting + Delaunay + circumcentre test, no repair), the baseline.

Usage (from the repository root)::

    python benchmarks/run_benchmarks.py --quick                        # 10,000 cells, four shapes
    python benchmarks/run_benchmarks.py --output benchmarks/results.md # 10,000 and 136,000 cells

See benchmarks/README.md for the meaning of each column.
"""
from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE_ROOT = HERE.parent / "filters"
if str(SOURCE_ROOT) not in sys.path:
    sys.path.insert(0, str(SOURCE_ROOT))

from shape_worker import (BASELINES, BOUNDARY_DISTANCE_LIMIT, NOISE_PER_SIZE, POINT_SPACING_PER_R,  # noqa: E402
                          SEED, SHAPES)

#: the steps of pipeline.run, in order (the keys of MeshingResult.seconds)
STEPS = ("implicit fit", "implicit sampling", "biting", "delaunay", "spurious cells", "quality", "fidelity")
#: the steps the baselines share with bitemesh on the same grid I (the fidelity check is bitemesh's alone).
MESH_STEPS = STEPS[2:6]
#: what the paper reports (section 5), on a Pentium M 2.2 GHz
PAPER = {"die": dict(cells=10_000, seconds=5.0, q_mean=0.80, q_std=0.15),
         "heart": dict(cells=136_000, seconds=300.0, q_mean=0.79, q_std=0.16)}
#: thresholds of the "suspicious" list
VOLUME_ERROR_LIMIT = 2.0   # percent
Q_MEAN_LIMIT = 0.78


# --- driver side ---------------------------------------------------------------------------------------------------

def run_worker(kind: str, name: str, size: int, workdir: Path, tag: str, timeout: float,
               profile_dir: Path | None) -> dict:
    """Run one worker in a fresh interpreter; return its record with the child's own peak RSS (os.wait4)."""
    out, log = workdir / f"{tag}.{kind}.json", workdir / f"{tag}.{kind}.log"
    command = [sys.executable, str(HERE / "shape_worker.py"), kind, name, str(size), "--json", str(out),
               "--grid", str(workdir / f"{tag}.grid.npz")]
    if profile_dir is not None:
        command += ["--profile", str(profile_dir / f"profile_{name}_{size}_{kind}")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(SOURCE_ROOT), os.environ.get("PYTHONPATH")])))
    clock = time.perf_counter()
    with open(log, "w") as stream:
        process = subprocess.Popen(command, stdout=stream, stderr=subprocess.STDOUT, env=env)
        # os.wait4 gives this child's own rusage; RUSAGE_CHILDREN would be the maximum over all children so far.
        while True:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - clock > timeout:
                process.kill()
                pid, status, usage = os.wait4(process.pid, 0)
                break
            time.sleep(0.05)
        process.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - clock
    if out.exists():
        record = json.loads(out.read_text())
    else:
        tail = log.read_text()[-2000:]
        reason = "timed out" if wall > timeout else f"exit code {process.returncode}"
        record = dict(ok=False, error=f"worker {reason} after {wall:.0f} s", traceback=tail)
    record.update(peak_rss_mb=usage.ru_maxrss / 1024.0, process_seconds=wall)
    return record


def machine_info() -> dict:
    import numpy
    import scipy
    model = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    memory = "unknown"
    try:
        kib = int(Path("/proc/meminfo").read_text().split()[1])
        memory = f"{kib / 2**20:.1f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    try:
        commit = subprocess.run(["git", "-C", str(HERE.parent), "describe", "--always", "--dirty"],
                                capture_output=True, text=True, timeout=10).stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    digest = hashlib.sha1()
    for path in sorted((SOURCE_ROOT / "bitemesh" / "core").rglob("*.py")):  # what the benchmark runs
        digest.update(path.read_bytes())
    commit += f", bitemesh/core sha1 {digest.hexdigest()[:10]}"
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    threads = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
               if k in os.environ}
    return dict(cpu=model, cpu_count=os.cpu_count(), usable_cpus=affinity, memory=memory,
                platform=platform.platform(), python=platform.python_version(), numpy=numpy.__version__,
                scipy=scipy.__version__, bitemesh_commit=commit, threads=threads or "library defaults")


def _median(values):
    return statistics.median(values) if values else float("nan")


def summarize_case(name: str, size: int, runs: list) -> dict:
    """One table row from the repeats of a case: medians of the times, the first run's metrics."""
    good = [r for r in runs if r["pipeline"].get("ok")]
    case = dict(shape=name, size=size, repeats=len(runs), runs=runs)
    if not good:
        case["error"] = runs[0]["pipeline"].get("error", "unknown")
        return case
    first = good[0]["pipeline"]
    case.update(pipeline=first, metrics=first["metrics"],
                seconds={step: _median([r["pipeline"]["seconds"].get(step, 0.0) for r in good]) for step in STEPS},
                total_seconds=_median([r["pipeline"]["total_seconds"] for r in good]),
                cpu_seconds=_median([r["pipeline"]["cpu_seconds"] for r in good]),
                total_min=min(r["pipeline"]["total_seconds"] for r in good),
                total_max=max(r["pipeline"]["total_seconds"] for r in good),
                peak_rss_mb=max(r["pipeline"]["peak_rss_mb"] for r in good),
                deterministic=len({r["pipeline"]["metrics"]["mesh_sha1"] for r in good}) == 1)
    base = [r["baseline"] for r in good if r.get("baseline", {}).get("ok")]
    if base:
        case["baseline_peak_rss_mb"] = max(b["peak_rss_mb"] for b in base)
        case["baselines"] = {
            variant: dict(metrics=base[0]["variants"][variant]["metrics"],
                          seconds={s: _median([b["variants"][variant]["seconds"].get(s, 0.0) for b in base])
                                   for s in MESH_STEPS},
                          mesh_seconds=_median([b["variants"][variant]["mesh_seconds"] for b in base]))
            for variant in BASELINES}
    elif good[0].get("baseline"):
        case["baseline_error"] = good[0]["baseline"].get("error", "unknown")
    return case


def _validity(m: dict) -> str:
    ok = m["valid"] and m["euler"] == m["expected_euler"] and m["components"] == 1
    return "yes" if ok else "**no**"


def suspicious(case: dict) -> list:
    """Human-readable findings that a reader of the table should not miss."""
    label = f"{case['shape']} {case['size']:,}"
    if "metrics" not in case:
        return [f"{label}: the pipeline FAILED: {case.get('error')}"]
    m, found = case["metrics"], []
    if m["problems"]:
        found.append(f"{label}: check_valid_domain reports {'; '.join(m['problems'])}")
    if m["euler"] != m["expected_euler"]:
        found.append(f"{label}: boundary Euler characteristic {m['euler']}, expected {m['expected_euler']}")
    if m["components"] != 1:
        found.append(f"{label}: {m['components']} connected components")
    if abs(m["volume_error_percent"]) > VOLUME_ERROR_LIMIT:
        found.append(f"{label}: volume error {m['volume_error_percent']:+.2f} % (limit {VOLUME_ERROR_LIMIT} %)")
    if m["q_mean"] < Q_MEAN_LIMIT:
        found.append(f"{label}: mean Q {m['q_mean']:.3f} < {Q_MEAN_LIMIT}")
    if m["boundary_projected_max"] > BOUNDARY_DISTANCE_LIMIT * m["radius"]:
        found.append(f"{label}: {m['notch_vertices']} boundary vertices lie more than {BOUNDARY_DISTANCE_LIMIT} R "
                     f"from the true surface, the deepest {m['boundary_projected_max'] / m['radius']:.2f} R: "
                     "notches that bare interior nodes")
    if not case["deterministic"]:
        found.append(f"{label}: the repeats gave different meshes (same input and seed)")
    if m["projection_residual_max"] > 1e-6:
        found.append(f"{label}: boundary projection did not converge (|f| at foot {m['projection_residual_max']:.2g})")
    for run in case["runs"]:
        if run.get("baseline") and not run["baseline"].get("ok"):
            found.append(f"{label}: the baseline FAILED: {run['baseline'].get('error')}")
            break
    return found


def render(cases: list, machine: dict, args, started: datetime.datetime, elapsed: float) -> str:
    lines = [
        "# bitemesh benchmark",
        "",
        f"- date: {started.strftime('%Y-%m-%d %H:%M UTC')}, whole run {elapsed / 60:.1f} min",
        f"- machine: {machine['cpu']}, {machine['cpu_count']} CPUs ({machine['usable_cpus']} usable), "
        f"{machine['memory']} RAM, {machine['platform']}",
        f"- software: Python {machine['python']}, numpy {machine['numpy']}, scipy {machine['scipy']}, "
        f"bitemesh {machine['bitemesh_commit']}, threads: {machine['threads']}",
        f"- command: `python benchmarks/run_benchmarks.py {' '.join(args.argv)}`",
        f"- load average (1 min) at start {args.load[0]:.2f}, at end {os.getloadavg()[0]:.2f}: other work on the "
        "machine inflates the wall times; *CPU s* (the process's CPU time during the run) is less sensitive to it",
        f"- input: points on the analytic surface {POINT_SPACING_PER_R} R apart (R from the target cell count), "
        f"Gaussian noise {NOISE_PER_SIZE:.1%} of the shape's largest side, seed {SEED}; outward normals; "
        f"default parameters (MPU, grid spacing R/4, threshold 0.4); {args.repeat} repeat(s), each in a fresh process",
        "",
        "## bitemesh pipeline (scattered points -> valid mesh)",
        "",
        "| shape | target | cells | points | time s | CPU s | peak RSS MB | Q mean | Q std | Q min | % Q<0.1 | "
        "min dihedral ° | volume err % | bdist max /R | bdist mean /R | edge CV | valid | χ | parts |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for c in cases:
        if "metrics" not in c:
            lines.append(f"| {c['shape']} | {c['size']:,} | FAILED: {c.get('error', '')[:80]} |" + " |" * 16)
            continue
        m, r = c["metrics"], c["metrics"]["radius"]
        spread = f" ({c['total_min']:.1f}-{c['total_max']:.1f})" if c["repeats"] > 1 else ""
        lines.append(
            f"| {c['shape']} | {c['size']:,} | {m['cells']:,} | {m['points']:,} | {c['total_seconds']:.1f}{spread} | "
            f"{c['cpu_seconds']:.1f} | {c['peak_rss_mb']:.0f} | {m['q_mean']:.3f} | {m['q_std']:.3f} | "
            f"{m['q_min']:.4f} | "
            f"{m['percent_q_below_0_1']:.2f} | {m['min_dihedral']:.2f} | {m['volume_error_percent']:+.2f} | "
            f"{m['boundary_projected_max'] / r:.3f} | {m['boundary_projected_mean'] / r:.4f} | {m['edge_cv']:.3f} | "
            f"{_validity(m)} | {m['euler']}/{m['expected_euler']} | {m['components']} |")
    lines += [
        "",
        f"Paper (section 5, Pentium M 2.2 GHz): die {PAPER['die']['cells']:,} cells in about "
        f"{PAPER['die']['seconds']:.0f} s, Q {PAPER['die']['q_mean']:.2f} ± {PAPER['die']['q_std']:.2f}; "
        f"heart {PAPER['heart']['cells']:,} cells in about {PAPER['heart']['seconds'] / 60:.0f} min, "
        f"Q {PAPER['heart']['q_mean']:.2f} ± {PAPER['heart']['q_std']:.2f}.",
        "",
        "## Time per step (seconds, median of the repeats)",
        "",
        "| shape | target | input points | sampling the input* | " + " | ".join(STEPS) + " | total | grid I | "
        "RSS after import MB | peak RSS MB | baseline peak RSS MB** |",
        "|---|---:|---:|---:|" + "---:|" * len(STEPS) + "---:|---|---:|---:|---:|",
    ]
    for c in cases:
        if "metrics" not in c:
            continue
        p = c["pipeline"]
        lines.append(f"| {c['shape']} | {c['size']:,} | {p['n_input_points']:,} | {p['input_seconds']:.2f} | "
                     + " | ".join(f"{c['seconds'][s]:.2f}" for s in STEPS)
                     + f" | {c['total_seconds']:.2f} | {'x'.join(map(str, p['grid_shape']))} | "
                     f"{p['rss_after_import_mb']:.0f} | {c['peak_rss_mb']:.0f} | "
                     + (f"{c['baseline_peak_rss_mb']:.0f} |" if "baseline_peak_rss_mb" in c else "n/a |"))
    lines += ["", "\\* not part of the pipeline, not counted in the total. Peak RSS: the worker process's own "
              "ru_maxrss (os.wait4), interpreter and imports included. \\*\\* the baseline process loads the "
              "saved grid I and meshes it twice; it does not fit the implicit.", "",
              "## Baselines on the same grid I: what the repair changes",
              "",
              "*paper*: biting + Delaunay + the circumcentre test alone (section 4.2.2, threshold 0.4). "
              "*outside_cells*: the same with bitemesh's current outside test (circumcentre test and its "
              "refinements), no repair. *bitemesh*: the pipeline (outside test, then carve_domain's repair). "
              "Time = the implicit fit and sampling (shared, the same grid I) + the mesh steps (biting, Delaunay, "
              "outside test and repair, quality); the ratio is to *paper*.",
              "",
              "| shape | target | method | cells | time s | ratio | mesh steps s | ratio | Q mean | Q std | Q min | "
              "% Q<0.1 | min dihedral ° | volume err % | bdist max /R | parts | χ | problems (check_valid_domain) |",
              "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for c in cases:
        if "metrics" not in c:
            continue
        if "baselines" not in c:
            what = f"FAILED: {c['baseline_error'][:80]}" if "baseline_error" in c else "not run"
            lines.append(f"| {c['shape']} | {c['size']:,} | baseline {what} |" + " |" * 15)
            continue
        shared = c["seconds"]["implicit fit"] + c["seconds"]["implicit sampling"]
        rows = [(variant, c["baselines"][variant]["metrics"], c["baselines"][variant]["mesh_seconds"])
                for variant in BASELINES]
        rows.append(("bitemesh", c["metrics"], sum(c["seconds"][s] for s in MESH_STEPS)))
        reference = rows[0][2]
        for variant, m, mesh_seconds in rows:
            problems = "; ".join(m["problems"]) or "none"
            lines.append(
                f"| {c['shape']} | {c['size']:,} | {variant} | {m['cells']:,} | {shared + mesh_seconds:.1f} | "
                f"{(shared + mesh_seconds) / (shared + reference):.2f} | {mesh_seconds:.2f} | "
                f"{mesh_seconds / reference:.2f} | {m['q_mean']:.3f} | {m['q_std']:.3f} | {m['q_min']:.4f} | "
                f"{m['percent_q_below_0_1']:.2f} | {m['min_dihedral']:.2f} | {m['volume_error_percent']:+.2f} | "
                f"{m['boundary_projected_max'] / m['radius']:.3f} | {m['components']} | "
                f"{m['euler']}/{m['expected_euler']} | {problems} |")
    lines += ["",
              "## Distance of the boundary vertices to the true surface",
              "",
              "*\\|f\\|*: the analytic function at the boundary vertices (a signed distance only approximately: first "
              "order for the ellipsoids of the two-cavity shell, a bound near the creases of a CSG). *projected*: the "
              "distance to the foot of Newton steps onto f = 0, an upper bound of the true distance. *lower*: the "
              "distance to the nearest full surface of the CSG pieces (exact ellipsoid distance by bisection), a "
              "lower bound (n/a: not derived for the die). The true distance lies in [lower, projected]. Units: the "
              "shape's (sphere radius 1).",
              "",
              "| shape | target | R | boundary vertices | \\|f\\| max | \\|f\\| mean | projected max | "
              "projected mean | lower max | lower mean | max (projected - lower) | max \\|\\|f\\| - projected\\| | "
              f"vertices > {BOUNDARY_DISTANCE_LIMIT} R |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for c in cases:
        if "metrics" not in c:
            continue
        m = c["metrics"]
        bound = ("n/a | n/a | n/a" if m["lower_bound_max"] is None else
                 f"{m['lower_bound_max']:.2e} | {m['lower_bound_mean']:.2e} | {m['bracket_width_max']:.1e}")
        lines.append(f"| {c['shape']} | {c['size']:,} | {m['radius']:.4f} | {m['boundary_points']:,} | "
                     f"{m['boundary_f_max']:.2e} | {m['boundary_f_mean']:.2e} | {m['boundary_projected_max']:.2e} | "
                     f"{m['boundary_projected_mean']:.2e} | {bound} | "
                     f"{max(m['f_minus_projected_max'], m['projected_minus_f_max']):.1e} | {m['notch_vertices']} |")
    found = [item for c in cases for item in suspicious(c)]
    lines += ["", "## Suspicious", ""] + ([f"- {item}" for item in found] or ["- nothing"])
    lines += ["", f"Thresholds: invalid domain, χ or parts unexpected, |volume error| > {VOLUME_ERROR_LIMIT} %, "
              f"mean Q < {Q_MEAN_LIMIT}, boundary vertex deeper than {BOUNDARY_DISTANCE_LIMIT} R, failures, repeats "
              "that differ.", ""]
    return "\n".join(lines)


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 136000], help="target cell counts")
    parser.add_argument("--shapes", nargs="+", default=list(SHAPES), choices=list(SHAPES), help="analytic shapes")
    parser.add_argument("--repeat", type=int, default=1, help="runs per case, each in a fresh process")
    parser.add_argument("--output", default="results.md", help="markdown file to write (raw JSON beside it)")
    parser.add_argument("--quick", action="store_true", help="10,000 cells only")
    parser.add_argument("--no-baseline", action="store_true", help="skip the paper's plain method")
    parser.add_argument("--timeout", type=float, default=3600.0, help="seconds a worker may take")
    parser.add_argument("--profile", metavar="DIR", help="run every worker under cProfile, write stats into DIR")
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    if args.quick:
        args.sizes = [10000]
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    return args


def main(argv=None) -> int:
    args = parse(argv)
    started, clock = datetime.datetime.now(datetime.timezone.utc), time.perf_counter()
    args.load = os.getloadavg()
    machine = machine_info()
    profile_dir = Path(args.profile).resolve() if args.profile else None
    if profile_dir:
        profile_dir.mkdir(parents=True, exist_ok=True)
    cases = []
    with tempfile.TemporaryDirectory(prefix="bitemesh-bench-") as temporary:
        workdir = Path(temporary)
        for size in args.sizes:
            for name in args.shapes:
                runs = []
                for repeat in range(args.repeat):
                    tag = f"{name}-{size}-{repeat}"
                    print(f"[{time.perf_counter() - clock:7.1f} s] {tag}: pipeline", file=sys.stderr, flush=True)
                    run = dict(pipeline=run_worker("pipeline", name, size, workdir, tag, args.timeout, profile_dir))
                    if run["pipeline"].get("ok") and not args.no_baseline:
                        print(f"[{time.perf_counter() - clock:7.1f} s] {tag}: baseline", file=sys.stderr, flush=True)
                        run["baseline"] = run_worker("baseline", name, size, workdir, tag, args.timeout, profile_dir)
                    (workdir / f"{tag}.grid.npz").unlink(missing_ok=True)
                    for kind, record in run.items():
                        if not record.get("ok"):
                            print(f"  {kind} failed: {record.get('error')}\n{record.get('traceback', '')}",
                                  file=sys.stderr, flush=True)
                    runs.append(run)
                cases.append(summarize_case(name, size, runs))
    text = render(cases, machine, args, started, time.perf_counter() - clock)
    print(text)
    output = Path(args.output)
    output.write_text(text)
    output.with_suffix(".json").write_text(json.dumps(dict(machine=machine, argv=args.argv, date=started.isoformat(),
                                                           cases=cases), indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
