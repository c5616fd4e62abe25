"""Every core and the first run (issue 35): meshes on 1 thread against every core, side by side in one run, and
the first ``bitemesh demo`` after ``pip install .`` against a later one.

    python benchmarks/threads.py [--repeats 3] [--out benchmarks/threads.md]

Threads: each case (the shipped biv-me heart at the default size; a sphere of scattered points at about 136,000
cells) is meshed ``--repeats`` times on 1 thread and on every core, alternating, in fresh processes; the report
gives each step's median and checks that both counts give the same mesh bit for bit.  First run: the wheel
``pip install .`` builds (its build compiles the kernels into it, setup.py) is built once, timed, and installed
into a new folder for each repeat, where ``bitemesh demo`` runs in a fresh process; for comparison, the demo from
the source tree with ``NUMBA_CACHE_DIR`` an empty folder (every kernel compiled: an editable install, or a numba
other than the build's), then again with that folder filled; the compile events are counted by numba's event API.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
FILTERS = HERE.parent / "filters"
GPFILE = FILTERS / "bitemesh" / "data" / "bivme_patient1" / "GPFile_000.txt"

#: run in a fresh interpreter: one mesh on THREADS threads, its steps' seconds and its hash as JSON
MESH_WORKER = """
import hashlib, json, sys, time
import numpy as np
import bitemesh
from bitemesh.core.shapes import sample_surface, sphere
case, threads = sys.argv[1], int(sys.argv[2])
if case == "heart":
    data = sys.argv[3]
else:
    shape = sphere()
    data = bitemesh.Samples(*sample_surface(shape, spacing=0.012, noise=0.002, seed=0))
bitemesh.mesh(data, cells=2000, threads=threads)   # kernels loaded before the clock
start = time.perf_counter()
result = bitemesh.mesh(data, threads=threads, **({} if case == "heart" else {"cells": 136000}))
wall = time.perf_counter() - start
digest = hashlib.sha256(result.mesh.points.tobytes() + result.mesh.cells.tobytes()).hexdigest()[:16]
print(json.dumps({"wall": wall, "seconds": result.seconds, "cells": len(result.mesh.cells), "hash": digest}))
"""

#: run in a fresh interpreter: each threaded kernel on a 136,000-cell sphere (its mesh, grid and samples) on 1 thread
#: and on THREADS, medians of REPEATS calls each, the counts alternating; JSON name -> [1 thread, THREADS] seconds
KERNEL_WORKER = """
import json, statistics, sys, time
import numpy as np
import bitemesh
from bitemesh.core.compiled import using_threads
from bitemesh.core.implicit.mpu import fit_mpu
from bitemesh.core.mesh.quality import dihedral_angles, signed_radius_ratio
from bitemesh.core.mesh.simplicial import circumspheres
from bitemesh.core.optimize.measures import inverse_mean_ratio, mean_ratio_terms
from bitemesh.core.shapes import sample_surface, sphere
threads, repeats = int(sys.argv[1]), int(sys.argv[2])
points, normals = sample_surface(sphere(), spacing=0.012, noise=0.002, seed=0)
result = bitemesh.mesh(bitemesh.Samples(points, normals), cells=136000, optimize=0)
mesh, grid = result.mesh, result.implicit
inside = np.random.default_rng(0).uniform(grid.origin, grid.upper, (300000, 3))
kernels = {"radius ratios": lambda: signed_radius_ratio(mesh.points, mesh.cells),
           "dihedral angles": lambda: dihedral_angles(mesh.points, mesh.cells),
           "circumspheres": lambda: circumspheres(mesh.points, mesh.cells),
           "inverse mean ratio": lambda: inverse_mean_ratio(mesh.points, mesh.cells),
           "mean ratio terms": lambda: mean_ratio_terms(mesh.points, mesh.cells),
           "f at 300,000 points (grid)": lambda: grid.evaluate(inside),
           "Newton steps to f = 0": lambda: grid.project(inside[:100000]),
           "MPU fit (k-d queries)": lambda: fit_mpu(points, normals)}
seconds = {name: {1: [], threads: []} for name in kernels}
for name, call in kernels.items():
    for _ in range(repeats):
        for count in (1, threads):
            with using_threads(count):
                call()
                start = time.perf_counter()
                call()
                seconds[name][count].append(time.perf_counter() - start)
print(json.dumps({name: [statistics.median(times[1]), statistics.median(times[threads])]
                  for name, times in seconds.items()}))
"""

#: run in a fresh interpreter: bitemesh demo, timed from before the import, with numba's compile events counted
DEMO_WORKER = """
import sys, time
start = time.perf_counter()
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        compiled.append(ev)
event.register("numba:compile", Count())
from bitemesh.cli import main
main(["demo", "-o", sys.argv[1]])
print("RESULT", time.perf_counter() - start, len(compiled))
"""


def fresh(code: str, *args, path: Path = FILTERS, cache: Path | None = None) -> str:
    """The output of ``code`` run with ``args`` in a fresh interpreter that imports bitemesh from ``path``, with
    numba's cache in ``cache`` (else where numba puts it: the package's ``__pycache__`` folders)."""
    environment = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}
    environment.update({"PYTHONPATH": str(path)}, **({"NUMBA_CACHE_DIR": str(cache)} if cache else {}))
    completed = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                               env=environment, check=True)
    return completed.stdout


def pip(*args) -> float:
    """Seconds ``pip`` took with ``args``."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pip", "-q", *args], capture_output=True, check=True)
    return time.perf_counter() - start


def mesh_runs(case: str, counts, repeats: int) -> dict:
    """count -> list of the worker's JSON results, the counts alternating."""
    runs = {count: [] for count in counts}
    for _ in range(repeats):
        for count in counts:
            runs[count].append(json.loads(fresh(MESH_WORKER, case, count, GPFILE).strip().splitlines()[-1]))
    return runs


def kernel_runs(threads: int, repeats: int) -> dict:
    """Kernel name -> [seconds on 1 thread, on ``threads``] (:data:`KERNEL_WORKER`)."""
    return json.loads(fresh(KERNEL_WORKER, threads, repeats).strip().splitlines()[-1])


def demo_runs(repeats: int) -> dict:
    """"installed" / "empty" / "filled" -> list of (seconds, kernels compiled) of the demo; "build" -> [seconds of
    ``pip wheel .``]."""
    runs = {"build": [], "installed": [], "empty": [], "filled": []}
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        source = folder / "source"   # what pip builds from, without an earlier build's folder
        shutil.copytree(FILTERS, source / "filters", ignore=shutil.ignore_patterns("__pycache__"))
        for name in ("pyproject.toml", "setup.py", "README.md"):
            shutil.copy(HERE.parent / name, source)
        runs["build"].append(pip("wheel", "--no-deps", str(source), "-w", str(folder)))
        wheel = next(folder.glob("bitemesh-*.whl"))
        for repeat in range(repeats):
            target = folder / f"installed{repeat}"
            pip("install", "--no-deps", "--target", str(target), str(wheel))
            cache = folder / f"cache{repeat}"   # empty, then filled by the first run
            for state, path in (("installed", target), ("empty", FILTERS), ("filled", FILTERS)):
                line = fresh(DEMO_WORKER, folder / "die.vtu", path=path, cache=None if path == target else cache)
                seconds, kernels = line.split("RESULT")[-1].split()
                runs[state].append((float(seconds), int(kernels)))
    return runs


def report(meshes: dict, kernels: dict, demo: dict, counts, repeats: int) -> str:
    most = counts[-1]
    lines = ["# Every core and the first run", "",
             f"`python benchmarks/threads.py --repeats {repeats}` on this {os.cpu_count()}-core machine "
             f"({time.strftime('%Y-%m-%d')}); medians of {repeats} fresh processes each, the thread counts "
             "alternating so that the machine's noise falls on both.", "",
             f"| case | cells | 1 thread (s) | {most} threads (s) | ratio | same mesh |", "|---|---|---|---|---|---|"]
    for case, runs in meshes.items():
        walls = {count: statistics.median(run["wall"] for run in runs[count]) for count in counts}
        hashes = {run["hash"] for count in counts for run in runs[count]}
        lines.append(f"| {case} | {runs[1][0]['cells']:,} | {walls[1]:.2f} | {walls[most]:.2f} | "
                     f"{walls[most] / walls[1]:.2f} | {'yes' if len(hashes) == 1 else 'NO'} |")
    steps = list(dict.fromkeys(step for runs in meshes.values() for step in runs[1][0]["seconds"]))
    lines += ["", "Per step (median seconds, 1 thread / every core; - where the case has no such step):", "",
              "| case | " + " | ".join(steps) + " |", "|---|" + "---|" * len(steps)]
    for case, runs in meshes.items():
        cells = [f"{statistics.median(run['seconds'][step] for run in runs[1]):.2f} / "
                 f"{statistics.median(run['seconds'][step] for run in runs[most]):.2f}"
                 if step in runs[1][0]["seconds"] else "-" for step in steps]
        lines.append(f"| {case} | " + " | ".join(cells) + " |")
    lines += ["", f"Per threaded kernel, on a 136,000-cell sphere (median of {repeats} calls, in one process; the "
              "scaling each would give on more cores is at most its ratio's share of a mesh):", "",
              f"| kernel | 1 thread (s) | {most} threads (s) | speed-up |", "|---|---|---|---|"]
    lines += [f"| {name} | {one:.3f} | {many:.3f} | {one / many:.2f}x |" for name, (one, many) in kernels.items()]
    median = {state: statistics.median(seconds for seconds, _ in demo[state])
              for state in ("installed", "empty", "filled")}
    lines += ["", "## The first run", "",
              f"`pip wheel --no-deps .` (what `pip install .` builds, the kernels compiled into it): "
              f"{demo['build'][0]:.1f} s.", "",
              "| bitemesh | `bitemesh demo` from the start of Python (s) | kernels compiled |", "|---|---|---|",
              f"| installed from that wheel (the first run after `pip install .`) | {median['installed']:.1f} | "
              f"{demo['installed'][0][1]} |",
              f"| numba's cache empty (an editable install, or a numba other than the build's) | "
              f"{median['empty']:.1f} | {demo['empty'][0][1]} |",
              f"| numba's cache filled (every later run) | {median['filled']:.1f} | {demo['filled'][0][1]} |",
              "", f"First run after install - warm: {median['installed'] - median['filled']:+.1f} s "
              f"(empty cache - warm: {median['empty'] - median['filled']:+.1f} s).", ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    counts = sorted({1, os.cpu_count() or 1})
    meshes = {case: mesh_runs(case, counts, args.repeats) for case in ("heart", "sphere")}
    kernels = kernel_runs(counts[-1], args.repeats)
    text = report(meshes, kernels, demo_runs(args.repeats), counts, args.repeats)
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
