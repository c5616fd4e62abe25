#!/usr/bin/env python
"""The MeshOptimizer alone, timed and profiled on a saved input, its result compared bit for bit.

    python benchmarks/optimize_profile.py capture SHAPE SIZE IN.pkl    # the pipeline's grid and mesh before optimize
    python benchmarks/optimize_profile.py run IN.pkl [--profile P] [--save OUT.npz] [--compare REF.npz]

``capture`` runs the pipeline (the sampling of ``shape_worker.py``) with ``optimize=1`` and pickles what
``optimize_mesh`` gets.  ``run`` times ``optimize_mesh`` on it, prints its progress messages (the mean radius ratio
per relaxation iteration and sliver round) and, with ``--profile``, writes P.cumulative.txt and P.tottime.txt.
"""
from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

from bitemesh.core.optimize import optimizer as optimize  # noqa: E402
from bitemesh.core.steps import spine  # noqa: E402
from bitemesh.core.parameters import BitingParameters, OptimizeParameters  # noqa: E402
from bitemesh.core.sources.points import run  # noqa: E402
from bitemesh.core.mesh.quality import quality_summary  # noqa: E402


def capture(shape: str, size: int, path: str) -> None:
    """Pickle (grid, mesh, parameters) as the pipeline hands them to ``optimize_mesh``."""
    from shape_worker import SEED, make_input
    _, points, normals, _ = make_input(shape, size)
    real = spine.optimize_mesh

    def keep(grid, mesh, parameters, progress=None):
        Path(path).write_bytes(pickle.dumps((grid, mesh, parameters)))
        return real(grid, mesh, parameters, progress=progress)
    spine.optimize_mesh = keep
    try:
        run(points, normals, biting=BitingParameters(cells=size, seed=SEED), optimize=OptimizeParameters(optimize=1))
    finally:
        spine.optimize_mesh = real


def run_saved(path: str, profile: str | None, save: str | None, compare: str | None) -> None:
    """Time ``optimize_mesh`` on a captured input; print its messages, quality, and the comparison."""
    grid, mesh, parameters = pickle.loads(Path(path).read_bytes())
    messages = []
    profiler = None
    if profile:
        import cProfile
        profiler = cProfile.Profile()
        profiler.enable()
    clock, cpu = time.perf_counter(), time.process_time()
    result = optimize.optimize_mesh(grid, mesh, parameters, progress=lambda f, m: messages.append(m))
    seconds, cpu = time.perf_counter() - clock, time.process_time() - cpu
    if profiler is not None:
        import io
        import pstats
        profiler.disable()
        for sort in ("cumulative", "tottime"):
            text = io.StringIO()
            pstats.Stats(profiler, stream=text).sort_stats(sort).print_stats(45)
            Path(f"{profile}.{sort}.txt").write_text(text.getvalue())
    for message in messages:
        if "mean radius ratio" in message:
            print(" ", message)
    summary = quality_summary(result)
    print(f"{len(mesh.cells)} -> {len(result.cells)} cells in {seconds:.2f} s (CPU {cpu:.2f} s); "
          f"Q mean {summary.q_mean:.4f} min {summary.q_min:.4f}, min dihedral {summary.angle_min:.2f}, "
          f"edge CV {summary.edge_cv:.4f}, volume {summary.total_volume:.6f} "
          f"(input {quality_summary(mesh).total_volume:.6f})")
    if save:
        np.savez(save, points=result.points, cells=result.cells)
    if compare:
        with np.load(compare) as reference:
            same = np.array_equal(reference["points"], result.points) and np.array_equal(reference["cells"],
                                                                                         result.cells)
        print("identical to", compare, ":", same)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    grab = commands.add_parser("capture")
    grab.add_argument("shape")
    grab.add_argument("size", type=int)
    grab.add_argument("path")
    timing = commands.add_parser("run")
    timing.add_argument("path")
    timing.add_argument("--profile")
    timing.add_argument("--save")
    timing.add_argument("--compare")
    args = parser.parse_args(argv)
    if args.command == "capture":
        capture(args.shape, args.size, args.path)
    else:
        run_saved(args.path, args.profile, args.save, args.compare)
    return 0


if __name__ == "__main__":
    sys.exit(main())
