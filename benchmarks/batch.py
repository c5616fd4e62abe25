"""Cohort throughput: ``bitemesh.batch`` on 1 and 2 workers against a plain loop over the same cases.

    python benchmarks/batch.py [--cases 8] [--cells 8000] [--repeats 3] [--out benchmarks/batch.md]

The cases are scattered points of four shapes (die, sphere, torus, two-cavity shell) at two sampling seeds, each
meshed with the same options.  The plain loop meshes them one after the other in this process as
``bitemesh mesh`` does (``bitemesh.mesh`` then ``write_mesh``), with one BLAS thread like Dask's workers.  Each batch
starts its own LocalCluster; its start and its workers' warm-up are timed apart from the cases.  The runs take
turns (loop, two plain loops side by side, 1 worker, 2 workers) ``--repeats`` times, and the report gives the
median of each, so that a burst of others' work on the shared machine falls on all of them.  Writes a markdown
report.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):   # before numpy loads
    os.environ.setdefault(_name, "1")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))

import numpy as np  # noqa: E402

from bitemesh.meshing import mesh  # noqa: E402
from bitemesh.cohorts.run import batch  # noqa: E402
from bitemesh.core.shapes import die, sample_surface, sphere, torus, two_cavity_shell  # noqa: E402
from bitemesh.io import write_mesh  # noqa: E402

SHAPES = {"die": die, "sphere": sphere, "torus": torus, "shell": two_cavity_shell}


def make_cases(folder: Path, count: int) -> list:
    """``count`` point files (x y z nx ny nz) of the shapes, sampled every 0.04 with 0.1 % noise."""
    files = []
    for number in range(count):
        name = list(SHAPES)[number % len(SHAPES)]
        points, normals = sample_surface(SHAPES[name](), 0.04, noise=0.002, seed=number)
        path = folder / f"{name}_{number}.xyz"
        np.savetxt(path, np.hstack([points, normals]))
        files.append(path)
    return files


def cpu(who) -> float:
    """CPU seconds (user + system) of this process or of its finished children (the cluster's workers)."""
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def plain_loop(files, options, folder: Path) -> tuple:
    """(wall seconds, CPU seconds) of meshing and writing every case in this process."""
    start, start_cpu = time.perf_counter(), cpu(resource.RUSAGE_SELF)
    _mesh_all(files, options, folder)
    return time.perf_counter() - start, cpu(resource.RUSAGE_SELF) - start_cpu


def _mesh_all(files, options, folder) -> None:
    for path in files:
        write_mesh(mesh(path, options).mesh, folder / f"{path.stem}.vtu")


def two_plain_processes(files, options, folder: Path) -> float:
    """Wall seconds of two plain loops side by side in two processes, half the cases each, no Dask: what this
    machine's two cores give two independent processes (memory, cache, others' work), the ceiling of 2 workers."""
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    start = time.perf_counter()
    processes = [context.Process(target=_mesh_all, args=(files[half::2], options, folder)) for half in (0, 1)]
    for process in processes:
        process.start()
    for process in processes:
        process.join()
        assert process.exitcode == 0, process.exitcode
    return time.perf_counter() - start


def warm_up() -> None:
    """What a worker's first case loads once (the meshing modules, numba's cached kernels, matplotlib for the cut's
    picture), by meshing and picturing a small sphere: a fixed cost of each worker per run, timed with the cluster's
    start rather than charged to the cases (the plain loop's process is warm from its first round on)."""
    from bitemesh.cohorts import run
    from bitemesh.core.parameters import BitingParameters
    from bitemesh.core.sources.points import run as mesh

    points, normals = sample_surface(sphere(), 0.1, seed=0)
    run.render_cut(mesh(points, normals, biting=BitingParameters(cells=500)).mesh)


def started(client, marks) -> None:
    client.run(warm_up)
    marks.setdefault("up", time.perf_counter())


def timed_batch(files, options, folder: Path, workers: int) -> tuple:
    """(seconds from the call to the Client's start and the workers' warm-up, wall seconds of the cases (until the
    last case is done), CPU seconds of the workers and of this process (scheduler, client), summary rows, seconds
    from the last case to the return: the cluster's close, summary.csv and report.html)."""
    marks = {"call": time.perf_counter()}

    def progress(fraction, message=""):
        marks["last"] = time.perf_counter()   # called as each case finishes

    before = cpu(resource.RUSAGE_CHILDREN), cpu(resource.RUSAGE_SELF)
    rows = batch(files, options, output_dir=folder, workers=workers, progress=progress,
                 on_client=lambda client: started(client, marks))
    end = time.perf_counter()   # the workers have ended: their CPU time is in RUSAGE_CHILDREN
    spent = cpu(resource.RUSAGE_CHILDREN) - before[0], cpu(resource.RUSAGE_SELF) - before[1]
    return marks["up"] - marks["call"], marks["last"] - marks["up"], spent, rows, end - marks["last"]


def median_of(rounds, value) -> float:
    """The median over the rounds of ``value(round)``."""
    return float(np.median([value(one) for one in rounds]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=8)
    parser.add_argument("--cells", type=int, default=8000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=HERE / "batch.md")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bitemesh-batch-benchmark"))
    args = parser.parse_args()
    options = {"cells": args.cells, "optimize": 1}
    work = args.work
    (work / "inputs").mkdir(parents=True, exist_ok=True)
    files = make_cases(work / "inputs", args.cases)
    rounds = []
    for _ in range(args.repeats):
        for folder in ("loop", "pair", "w1", "w2"):
            (work / folder).mkdir(parents=True, exist_ok=True)
            for old in (work / folder).glob("*.vtu"):
                old.unlink()
        for old in work.glob("w*/.bitemesh/*"):
            old.unlink()
        loop_run = plain_loop(files, options, work / "loop")
        pair = two_plain_processes(files, options, work / "pair")
        batch1 = timed_batch(files, options, work / "w1", 1)
        batch2 = timed_batch(files, options, work / "w2", 2)
        rounds.append((loop_run, batch1, batch2, pair))
    loop, loop_cpu = median_of(rounds, lambda r: r[0][0]), median_of(rounds, lambda r: r[0][1])
    start1, run1 = median_of(rounds, lambda r: r[1][0]), median_of(rounds, lambda r: r[1][1])
    cpu1 = median_of(rounds, lambda r: r[1][2][0]), median_of(rounds, lambda r: r[1][2][1])
    start2, run2 = median_of(rounds, lambda r: r[2][0]), median_of(rounds, lambda r: r[2][1])
    finish1, finish2 = median_of(rounds, lambda r: r[1][4]), median_of(rounds, lambda r: r[2][4])
    fixed = start2 + finish2   # once a run: the cluster's start, its workers' warm-up, its close and the report
    cpu2 = median_of(rounds, lambda r: r[2][2][0]), median_of(rounds, lambda r: r[2][2][1])
    pair = median_of(rounds, lambda r: r[3])
    rows = rounds[-1][1][3]
    assert all(row["status"] == "done" for row in rows), rows
    per_case = loop / len(files)
    overhead = (run1 - loop) / loop
    speedup = run1 / run2
    mean_cells = np.mean([row["cells"] for row in rows])
    lines = [
        "# Cohort throughput (`python benchmarks/batch.py`)",
        "",
        f"{len(files)} cases (die, sphere, torus, two-cavity shell from noisy scattered points, two seeds each), "
        f"`--cells {args.cells}` with the optimizer: {mean_cells:,.0f} cells on average. This project's shared "
        f"2-core machine (two other engineers at work), {time.strftime('%Y-%m-%d')}; wall-clock seconds, one BLAS "
        f"thread everywhere; medians of {args.repeats} rounds, the three runs taking turns in each. Every round, "
        "in order (loop / 1 worker / 2 workers, s): "
        + "; ".join(f"{r[0][0]:.1f} / {r[1][1]:.1f} / {r[2][1]:.1f}" for r in rounds) + "; two plain processes: "
        + ", ".join(f"{r[3]:.1f}" for r in rounds) + ".",
        "",
        "| run | cluster start + warm-up (s) | cases, wall until the last is done (s) | s per case | "
        "against the loop | CPU: workers + driver (s) |",
        "|---|---:|---:|---:|---:|---:|",
        f"| plain loop in one process | - | {loop:.1f} | {per_case:.2f} | 1.00 | {loop_cpu:.1f} |",
        f"| `bitemesh.batch`, 1 worker | {start1:.1f} | {run1:.1f} | {run1 / len(files):.2f} | {run1 / loop:.2f} | "
        f"{cpu1[0]:.1f} + {cpu1[1]:.1f} |",
        f"| `bitemesh.batch`, 2 workers | {start2:.1f} | {run2:.1f} | {run2 / len(files):.2f} | {run2 / loop:.2f} | "
        f"{cpu2[0]:.1f} + {cpu2[1]:.1f} |",
        "",
        f"- 2 workers against 1: **{speedup:.2f}x** the throughput (the goal: at least 1.7x). Two plain loops side "
        f"by side in two processes (half the cases each, no Dask) against the one loop: {loop / pair:.2f}x "
        f"({pair:.1f} s): the most two cores of this machine gave two independent processes in this run.",
        f"- Overhead per case against the plain loop: **{100 * overhead:+.1f} %** ({(run1 - loop) / len(files):+.2f} s "
        "a case: the task's hash, the record and the picture of the cut, Dask's scheduling; the goal: at most 5 %), "
        "and once per run the cluster's start and each worker's warm-up "
        f"(imports, numba's cached kernels, matplotlib: one small sphere meshed), {start1:.1f} s, and after the last "
        f"case the cluster's close, summary.csv and report.html, {finish1:.1f} s. "
        "In CPU seconds, steadier on a shared machine: "
        f"**{100 * (sum(cpu1) - loop_cpu) / loop_cpu:+.1f} %** (workers and driver against the loop; the workers' "
        f"CPU includes their start and imports, {cpu1[0] - loop_cpu:+.1f} s in all).",
        f"- Load average when the run ended: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (others' work "
        "included): 2 workers need 2 free cores to reach 2x.",
        f"- A 1,000-case cohort of such cases on N workers of this kind takes about {fixed:.0f} s + 1,000 x "
        f"{run1 / len(files):.2f} s / (N x e), e the parallel efficiency measured here "
        f"({speedup / 2:.2f} for N = 2): "
        + ", ".join(f"N = {n}: {(fixed + 1000 * run1 / len(files) / (n * (1 if n == 1 else speedup / 2))) / 60:.1f} "
                    "min" for n in (1, 2, 8, 32, 128)) + " (N = 1: e = 1).",
    ]
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
