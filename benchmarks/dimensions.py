#!/usr/bin/env python
"""The method in k dimensions (issue 36): the unit k-ball meshed from its analytic f at a given R, plain and relaxed,
each case in a fresh process so that its peak memory is its own.

    python benchmarks/dimensions.py 3:0.06 4:0.18 4:0.1 5:0.33 [--plain] [--out benchmarks/dimensions.md]

Each row: cells, nodes, the measure against the ball's (pi r^2, 4/3 pi r^3, pi^2 r^4 / 2, 8 pi^2 r^5 / 15) and
against the bound of the inscribed mesh (facets of circumradius rho leave the ball of radius sqrt(1 - rho^2)
inside), the deficit over (R / r)^2 (the inscribed mesh's error is of that order, its constant grows with k), the
radius ratio (mean, smallest, histogram of ten bins), the smallest cell measure against the regular simplex of
edge R, seconds by step, and the peak resident memory of the process.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from math import factorial, pi, sqrt
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: the unit k-ball's measure.
BALL = {2: pi, 3: 4 / 3 * pi, 4: pi**2 / 2, 5: 8 * pi**2 / 15}

WORKER = """
import json, resource, sys, time
import numpy as np
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.mesh.quality import radius_ratio
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.mesh.validity import check_valid_domain
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid
k, radius, optimize = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
clock = time.perf_counter()
grid = sample_function(lambda x: 1 - np.linalg.norm(x, axis=1), -np.ones(k), np.ones(k), radius / 4,
                       margin=radius / 2)
result = mesh_from_grid(grid, BitingParameters(radius=radius), optimize=OptimizeParameters(optimize=optimize))
seconds = time.perf_counter() - clock
mesh = result.mesh
quality = radius_ratio(mesh.points, mesh.cells)
measures = signed_measures(mesh.points, mesh.cells)
facets = boundary_facets(mesh.cells)
edges = mesh.points[facets[:, 1:]] - mesh.points[facets[:, :1]]   # each facet's circumcentre in its own plane
gram = np.einsum("fik,fjk->fij", edges, edges)
centre = np.linalg.solve(2 * gram, np.einsum("fii->fi", gram)[:, :, None])[:, :, 0]
rho = np.linalg.norm(np.einsum("fi,fik->fk", centre, edges), axis=1)
print(json.dumps({"k": k, "radius": radius, "optimize": optimize, "cells": len(mesh.cells),
                  "nodes": len(mesh.points), "measure": float(measures.sum()), "rho": float(rho.max()),
                  "valid": not check_valid_domain(mesh), "smallest": float(measures.min()),
                  "mean": float(quality.mean()), "least": float(quality.min()),
                  "histogram": np.histogram(quality, bins=10, range=(0, 1))[0].tolist(), "seconds": seconds,
                  "steps": {name: round(value, 1) for name, value in result.seconds.items()},
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def run(k: int, radius: float, optimize: int) -> dict:
    """One case in a fresh interpreter."""
    done = subprocess.run([sys.executable, "-c", WORKER, str(k), str(radius), str(optimize)], check=True,
                          capture_output=True, text=True, env={"PYTHONPATH": str(HERE.parent / "filters"),
                                                               "PATH": "/usr/bin:/bin"})
    return json.loads(done.stdout.strip().splitlines()[-1])


def row(case: dict) -> str:
    k, radius = case["k"], case["radius"]
    exact = BALL[k]
    deficit = 1 - case["measure"] / exact
    regular = radius**k * sqrt(k + 1) / (factorial(k) * 2 ** (k / 2))   # the regular k-simplex of edge R
    cells = [k, f"{radius:g}", "relaxed" if case["optimize"] else "plain", f"{case['cells']:,}", f"{case['nodes']:,}",
             f"{case['measure'] / exact:.4f}", f"{(1 - case['rho'] ** 2) ** (k / 2):.4f}", f"{deficit / radius**2:.2f}",
             f"{case['mean']:.3f}", f"{case['least']:.3f}", f"{case['smallest'] / regular:.1e}", case["histogram"],
             f"{case['seconds']:.0f}", f"{case['peak_mb']:.0f}", "yes" if case["valid"] else "NO"]
    return "| " + " | ".join(map(str, cells)) + " |"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", help="k:R, e.g. 4:0.18")
    parser.add_argument("--plain", action="store_true", help="each case plain (optimize=0) too")
    parser.add_argument("--out", type=Path, help="the Markdown table to write")
    args = parser.parse_args(argv)
    lines = ["| k | R | method | cells | nodes | measure / ball's | inscribed bound | deficit / R^2 | mean radius "
             "ratio | smallest | smallest measure / regular simplex's | radius ratio histogram (0-0.1 ... 0.9-1) | "
             "seconds | peak MB | valid |", "|" + "---|" * 15]
    print("\n".join(lines), flush=True)
    for case in args.cases:
        k, radius = case.split(":")
        for optimize in ((0, 1) if args.plain else (1,)):
            lines.append(row(run(int(k), float(radius), optimize)))
            print(lines[-1], flush=True)
    if args.out:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
