"""Cohort throughput: ``bitemesh.batch`` on 1 and 2 workers against a plain loop over the same cases.

    python benchmarks/batch.py [--cases 8] [--cells 8000] [--out benchmarks/batch.md]

The cases are scattered points of four shapes (die, sphere, torus, two-cavity shell) at two sampling seeds, each
meshed with the same options.  The plain loop meshes them one after the other in this process as
``bitemesh mesh`` does (``mesh_input`` then ``write_mesh``), with one BLAS thread like Dask's workers.  Each batch
starts its own LocalCluster; its start is timed apart (``Client`` up) from the cases.  Writes a markdown report.
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

from bitemesh.cohorts.meshing import mesh_input  # noqa: E402
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
    for path in files:
        write_mesh(mesh_input(path, options).mesh, folder / f"{path.stem}.vtu")
    return time.perf_counter() - start, cpu(resource.RUSAGE_SELF) - start_cpu


def timed_batch(files, options, folder: Path, workers: int) -> tuple:
    """(seconds from the call to the Client's start, wall seconds of the cases, CPU seconds of the workers and of
    this process (scheduler, client), summary rows)."""
    marks = {"call": time.perf_counter()}
    before = cpu(resource.RUSAGE_CHILDREN), cpu(resource.RUSAGE_SELF)
    rows = batch(files, options, output_dir=folder, workers=workers,
                 on_client=lambda client: marks.setdefault("up", time.perf_counter()))
    end = time.perf_counter()   # the workers have ended: their CPU time is in RUSAGE_CHILDREN
    spent = cpu(resource.RUSAGE_CHILDREN) - before[0], cpu(resource.RUSAGE_SELF) - before[1]
    return marks["up"] - marks["call"], end - marks["up"], spent, rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=8)
    parser.add_argument("--cells", type=int, default=8000)
    parser.add_argument("--out", type=Path, default=HERE / "batch.md")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bitemesh-batch-benchmark"))
    args = parser.parse_args()
    options = {"cells": args.cells, "optimize": 1}
    work = args.work
    for folder in ("inputs", "loop", "w1", "w2"):
        (work / folder).mkdir(parents=True, exist_ok=True)
        for old in (work / folder).glob("*.vtu"):
            old.unlink()
    for old in work.glob("w*/.bitemesh/*"):
        old.unlink()
    files = make_cases(work / "inputs", args.cases)
    loop, loop_cpu = plain_loop(files, options, work / "loop")
    start1, run1, cpu1, rows = timed_batch(files, options, work / "w1", 1)
    start2, run2, cpu2, _ = timed_batch(files, options, work / "w2", 2)
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
        "thread everywhere.",
        "",
        "| run | cluster start (s) | cases, wall (s) | s per case | against the loop | CPU: workers + driver (s) |",
        "|---|---:|---:|---:|---:|---:|",
        f"| plain loop in one process | - | {loop:.1f} | {per_case:.2f} | 1.00 | {loop_cpu:.1f} |",
        f"| `bitemesh.batch`, 1 worker | {start1:.1f} | {run1:.1f} | {run1 / len(files):.2f} | {run1 / loop:.2f} | "
        f"{cpu1[0]:.1f} + {cpu1[1]:.1f} |",
        f"| `bitemesh.batch`, 2 workers | {start2:.1f} | {run2:.1f} | {run2 / len(files):.2f} | {run2 / loop:.2f} | "
        f"{cpu2[0]:.1f} + {cpu2[1]:.1f} |",
        "",
        f"- 2 workers against 1: **{speedup:.2f}x** the throughput (the goal: at least 1.7x).",
        f"- Overhead per case against the plain loop: **{100 * overhead:+.1f} %** ({(run1 - loop) / len(files):+.2f} s "
        "a case: the task's hash, the record and the picture of the cut, Dask's scheduling; the goal: at most 5 %), "
        f"and once per run the cluster's start, {start1:.1f} s. In CPU seconds, steadier on a shared machine: "
        f"**{100 * (sum(cpu1) - loop_cpu) / loop_cpu:+.1f} %** (workers and driver against the loop; the workers' "
        f"CPU includes their start and imports, {cpu1[0] - loop_cpu:+.1f} s in all).",
        f"- Load average when the run ended: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (others' work "
        "included): 2 workers need 2 free cores to reach 2x.",
        f"- A 1,000-case cohort of such cases on N workers of this kind takes about {start2:.0f} s + 1,000 x "
        f"{run1 / len(files):.2f} s / (N x e), e the parallel efficiency measured here "
        f"({speedup / 2:.2f} for N = 2): "
        + ", ".join(f"N = {n}: {(start2 + 1000 * run1 / len(files) / (n * (1 if n == 1 else speedup / 2))) / 60:.1f} "
                    "min" for n in (1, 2, 8, 32, 128)) + " (N = 1: e = 1).",
    ]
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
