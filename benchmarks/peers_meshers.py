"""One mesher x one case of ``peers.py`` in its own process: its timed runs, its first mesh (npz) and a JSON record
with the peak memory of the whole process.

    python benchmarks/peers_meshers.py MESHER SHAPE CELLS --out DIR     (run by peers.py)

MESHER: ``bitemesh`` (``OptimizeParameters()``, the dataclass default, whatever it is at this commit),
``bitemesh-no-optimize`` (``OptimizeParameters(optimize=0)``), ``gmsh`` or ``tetgen``.  The peak memory is
VmHWM (see ``peak_mb``) at the end, after everything the process did: interpreter and imports, the input (bitemesh's
scattered points, TetGen's surface), the untimed calibration runs (gmsh, TetGen) and every timed run.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
for p in (str(HERE.parent / "filters"), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

MESHERS = ("bitemesh", "bitemesh-no-optimize", "gmsh", "tetgen")
#: a single run longer than this (s) is not repeated
SINGLE_RUN_LIMIT = 180.0
#: from this many cells bitemesh runs with max_memory_mb = BIG_MEMORY_MB
BIG_CELLS, BIG_MEMORY_MB = 5_000_000, 16_384
#: cases this large get one timed run
ONE_RUN_CELLS = 1_000_000
#: calibration: stop within this fraction of the target tet count, at most this many rounds
TOLERANCE, ROUNDS = 0.05, 5
#: above this target, calibrate on a proxy of target / 8 tets (size 2h), then accept a full run within LARGE_TOLERANCE
LARGE, LARGE_TOLERANCE = 50_000, 0.10


def peak_mb() -> float:
    """Peak resident set size of this process so far, MiB: VmHWM, the high-water mark of its own address space.

    Not ``ru_maxrss``: getrusage(2) keeps it across execve, so a worker's starts at its parent's RSS at the fork
    (measured: TetGen at 1M read 1,054 MiB after the parent had measured bitemesh's 1M meshes, 287 MiB alone).
    """
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed_runs(run_once, target: int, repeat: int):
    """Call ``run_once() -> (points, cells, seconds, cpu, extra)`` up to ``repeat`` times (once for a big case or a long
    run); the first run's mesh and extra, every run's seconds and CPU seconds."""
    points, cells, seconds, cpu, extra = run_once()
    times, cpus = [seconds], [cpu]
    while len(times) < repeat and target < ONE_RUN_CELLS and seconds < SINGLE_RUN_LIMIT:
        _, _, seconds, cpu, _ = run_once()
        times.append(seconds)
        cpus.append(cpu)
    return points, cells, times, cpus, extra


def _next_size(history, target: int) -> float:
    """The next h from the runs so far, [(h, tets)]: n ~ h^-p, p = 3 first, then the secant's (kept in [1, 4])."""
    (h, n), p = history[-1], 3.0
    if len(history) > 1 and history[-2][0] != h and history[-2][1] != n:
        p = float(np.clip(-np.log(n / history[-2][1]) / np.log(h / history[-2][0]), 1.0, 4.0))
    return h * (n / target) ** (1 / p)


def calibrate(mesh_at, h: float, target: int, accept: float = LARGE_TOLERANCE):
    """The size h at which ``mesh_at(h) -> (points, cells, ...)`` gives about ``target`` tets.

    Small targets: full-size runs (untimed) until within TOLERANCE, else the closest (the die's count jumps by 30 %
    between h = 0.166 and 0.168 in gmsh, at its pips' rims).  Big ones: h from a proxy of target / 8 at 2h
    (calibrated to TOLERANCE), then full-size runs until one is within ``accept``: that run is returned as well, to
    serve as the first timed run.  Returns (h, result or None).
    """
    history = []
    if target > LARGE:
        h = calibrate(mesh_at, 2 * h, target // 8, TOLERANCE)[0] / 2
        for _ in range(ROUNDS):
            result = mesh_at(h)
            if abs(len(result[1]) / target - 1) < accept:
                return h, result
            history.append((h, len(result[1])))
            h = _next_size(history, target)
        return h, None
    for _ in range(ROUNDS):
        history.append((h, len(mesh_at(h)[1])))
        if abs(history[-1][1] / target - 1) < TOLERANCE:
            break
        h = _next_size(history, target)
    return min(history, key=lambda run: abs(np.log(run[1] / target)))[0], None


def run_bitemesh(name: str, target: int, repeat: int, optimize: bool | None):
    """bitemesh's whole ``pipeline.run`` from noisy scattered points (``shape_worker.make_input``, seed 0)."""
    from shape_worker import SEED, make_input

    from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters, SpuriousParameters
    from bitemesh.core.sources.points import run
    parameters = OptimizeParameters() if optimize is None else OptimizeParameters(optimize=int(optimize))
    shape, points, normals, _ = make_input(name, target)
    steps, said = [], []
    # the default max_memory_mb (4 GiB) refuses the 10M sphere's grid of 246M nodes: given more, as a user would
    implicit = ImplicitParameters(max_memory_mb=BIG_MEMORY_MB) if target >= BIG_CELLS else ImplicitParameters()

    def once():
        clock, cpu = time.perf_counter(), time.process_time()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = run(points, normals, implicit, BitingParameters(cells=target, seed=SEED),
                         SpuriousParameters(), optimize=parameters)
        seconds, cpu = time.perf_counter() - clock, time.process_time() - cpu
        steps.append({k: round(v, 2) for k, v in result.seconds.items()})
        if not steps[1:]:  # the first run's warnings
            said.extend(str(w.message) for w in caught)
        return result.mesh.points, result.mesh.cells, seconds, cpu, dict(grid_nodes=int(np.prod(result.implicit.shape)))

    points_out, cells, times, cpus, extra = timed_runs(once, target, repeat)
    return points_out, cells, times, cpus, dict(extra, optimize=parameters.optimize, steps=steps[0], warnings=said,
                                                note=f"{len(points)} noisy input points"
                                                + (f", max_memory_mb={BIG_MEMORY_MB}" if target >= BIG_CELLS else ""))


def run_gmsh(name: str, target: int, repeat: int, shape):
    """gmsh from the exact CAD (``peers_cad``), size calibrated for about ``target`` tets (untimed)."""
    from peers_cad import gmsh_once

    def mesh_at(h):
        return gmsh_once(name, h) + ({},)

    h = (shape.measure / target * 6 * np.sqrt(2) * 1.2) ** (1 / 3)  # regular-tet guess, slightly coarse
    h, first = calibrate(mesh_at, h, target)
    first = [first] if first else []
    out = timed_runs(lambda: first.pop() if first else mesh_at(h), target, repeat)
    return out[:4] + (dict(note=f"OCC exact {name}, h = {h:.4f}"),)


def run_tetgen(name: str, target: int, repeat: int, shape):
    """TetGen -pq1.2a of a surface triangulation at edge h (``peers_surfaces``), h calibrated (untimed)."""
    from peers_surfaces import surface, tetgen_once
    made = {}

    def mesh_at(h):
        if h not in made:
            made.clear()
            made[h] = surface(name, shape, h)
        points, faces, how = made[h]
        maxvolume = h ** 3 / (6 * np.sqrt(2)) * 1.5
        clock = time.process_time()
        nodes, cells, seconds = tetgen_once(points, faces, maxvolume)
        return nodes, cells, seconds, time.process_time() - clock, dict(
            note=f"-pq1.2a{maxvolume:.3g} of {how}: {len(points)} nodes, {len(faces)} triangles (h = {h:.4f})")

    h = (shape.measure / target * 6 * np.sqrt(2)) ** (1 / 3)
    h, first = calibrate(mesh_at, h, target)
    first = [first] if first else []
    return timed_runs(lambda: first.pop() if first else mesh_at(h), target, repeat)


def work(mesher: str, name: str, target: int, repeat: int, out: Path) -> dict:
    """Run one mesher on one case; write its first mesh to OUT/mesh.npz; return the record."""
    from shape_worker import SHAPES

    from bitemesh.core import shapes
    shape = getattr(shapes, SHAPES[name])()
    imported = peak_mb()
    if mesher == "bitemesh":
        points, cells, times, cpus, extra = run_bitemesh(name, target, repeat, None)
    elif mesher == "bitemesh-no-optimize":
        points, cells, times, cpus, extra = run_bitemesh(name, target, repeat, False)
    elif mesher == "gmsh":
        points, cells, times, cpus, extra = run_gmsh(name, target, repeat, shape)
    else:
        points, cells, times, cpus, extra = run_tetgen(name, target, repeat, shape)
    np.savez(out / "mesh.npz", points=np.asarray(points, float), cells=np.asarray(cells, np.int64))
    return dict(extra, seconds=times, cpu_seconds=cpus, peak_mb=peak_mb(), after_import_mb=imported,
                ru_maxrss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)


def main(argv=None) -> int:
    """Run one case; write OUT/record.json (failures recorded in it, not raised)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mesher", choices=MESHERS)
    parser.add_argument("shape")
    parser.add_argument("cells", type=int)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        record = dict(work(args.mesher, args.shape, args.cells, args.repeat, args.out), ok=True)
    except Exception as error:  # noqa: BLE001 - a benchmark records a failure and goes on
        record = dict(ok=False, error=f"{type(error).__name__}: {error}", traceback=traceback.format_exc(),
                      peak_mb=peak_mb())
    (args.out / "record.json").write_text(json.dumps(record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
