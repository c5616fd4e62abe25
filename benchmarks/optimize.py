"""The MeshOptimizer, before and after, side by side in one run on the benchmark's inputs.

    python benchmarks/optimize.py [--sizes 10000] [--shapes sphere die torus two-cavity]

Each case meshes the same scattered points twice in this process (without, then with ``optimize``) and prints a
markdown table: quality, volume error against the exact shape, the deepest boundary vertex (distance to the true
surface / R), the edge-length coefficient of variation, validity and the time ratio.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))
sys.path.insert(0, str(HERE))

from shape_worker import SEED, SHAPES, make_input, mesh_metrics  # noqa: E402

from bitemesh.core.parameters import (BitingParameters, ImplicitParameters, OptimizeParameters,  # noqa: E402
                                      SpuriousParameters)
from bitemesh.core.sources.points import run  # noqa: E402

COLUMNS = ("cells", "q_mean", "q_min", "min_dihedral", "percent_q_below_0_3", "volume_error_percent", "edge_cv")


def case(name: str, size: int) -> list:
    shape, points, normals, _ = make_input(name, size)
    rows = []
    for optimize in (OptimizeParameters(optimize=0), OptimizeParameters()):
        clock = time.perf_counter()
        result = run(points, normals, ImplicitParameters(), BitingParameters(cells=size, seed=SEED),
                     SpuriousParameters(), optimize=optimize)
        seconds = time.perf_counter() - clock
        metrics = mesh_metrics(result.mesh, shape, result.radius, name)
        rows.append((bool(optimize.optimize), seconds, metrics))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000])
    parser.add_argument("--shapes", nargs="+", default=list(SHAPES), choices=list(SHAPES))
    args = parser.parse_args(argv)
    print("| shape | target | optimize | cells | Q mean | Q min | min dihedral ° | % Q<0.3 | volume err % | "
          "deepest boundary vertex /R | edge CV | valid | time s | time ratio |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|")
    for size in args.sizes:
        for name in args.shapes:
            rows = case(name, size)
            base = rows[0][1]
            for optimized, seconds, m in rows:
                print(f"| {name} | {size:,} | {'yes' if optimized else 'no'} | {m['cells']:,} | {m['q_mean']:.3f} | "
                      f"{m['q_min']:.3f} | {m['min_dihedral']:.1f} | {m['percent_q_below_0_3']:.2f} | "
                      f"{m['volume_error_percent']:+.2f} | {m['boundary_projected_max'] / m['radius']:.3f} | "
                      f"{m['edge_cv']:.3f} | {'yes' if m['valid'] else 'NO'} | {seconds:.1f} | {seconds / base:.2f} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
