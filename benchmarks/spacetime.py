#!/usr/bin/env python
"""The beating heart as one 4-D space-time mesh (issue 36): every frame of biv-me patient1's cine fitted as
``bitemesh mesh`` fits it, f(x, tau) linear in tau between frames (``core.sources.spacetime``), meshed in 4-D by the
plain method, and each frame's instant cut out of it, measured against the 3-D mesh of that frame at the same R.

Usage (from the repository root)::

    python benchmarks/spacetime.py                          # 25 frames, R = 5 mm, a frame = R along tau
    python benchmarks/spacetime.py --frames 8 --radius 6 --output benchmarks/spacetime.md
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))

from bitemesh.core.grid.sampled import EXACT_WITHIN, sample_function  # noqa: E402
from bitemesh.core.mesh.quality import radius_ratio  # noqa: E402
from bitemesh.core.mesh.simplicial import signed_measures  # noqa: E402
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain  # noqa: E402
from bitemesh.core.parameters import BitingParameters  # noqa: E402
from bitemesh.core.sources.contours.fit import labelled_implicit  # noqa: E402
from bitemesh.core.sources.contours.run import thinnest_wall  # noqa: E402
from bitemesh.core.sources.spacetime import SpaceTime, frame_instants  # noqa: E402
from bitemesh.core.steps.spine import mesh_from_grid  # noqa: E402
from bitemesh.io import read_labelled_points  # noqa: E402
from bitemesh.meshing import mesh  # noqa: E402

CINE = HERE.parent.parent / "shared" / "data" / "bivme_patient1_cine" / "guidepoints"


def volume(cells_mesh) -> float:
    return float(signed_measures(cells_mesh.points, cells_mesh.cells).sum()) / 1000.0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=25, help="the first N frames of the cycle")
    parser.add_argument("--radius", type=float, default=5.0, help="R (mm), in space and time")
    parser.add_argument("--step", type=float, default=None, help="mm of tau a frame (default R)")
    parser.add_argument("--output", type=Path)
    args = parser.parse_args(argv)
    radius, step = args.radius, args.step or args.radius
    clock = time.perf_counter()
    functions, lower, upper = [], np.full(3, np.inf), np.full(3, -np.inf)
    for frame in range(args.frames):
        points, labels, slices = read_labelled_points(CINE / f"GPFile_{frame:03d}.txt")
        function, low, high = labelled_implicit(points, labels, slices=slices, min_wall=thinnest_wall(radius))
        functions.append(function)
        lower, upper = np.minimum(lower, low), np.maximum(upper, high)
    fitted = time.perf_counter() - clock
    shape = SpaceTime(tuple(functions), step, beyond=2 * radius)
    lo, hi = shape.slab
    clock = time.perf_counter()
    spacing = radius / 2.5
    grid = sample_function(shape, np.r_[lower, lo], np.r_[upper, hi], spacing, margin=radius,
                           exact_within=EXACT_WITHIN * spacing)   # f kept exactly near f = 0 only, as the mesher does
    result = mesh_from_grid(grid, BitingParameters(radius=radius))
    meshed = time.perf_counter() - clock
    space_time = result.mesh
    quality = radius_ratio(space_time.points, space_time.cells)
    lines = [f"Space-time heart: {args.frames} frames, R = {radius:g} mm, {step:g} mm of tau a frame; grid "
             f"{' x '.join(map(str, grid.shape))}; fit {fitted:.0f} s, 4-D mesh {meshed:.0f} s "
             f"({', '.join(f'{k} {v:.0f} s' for k, v in result.seconds.items())})",
             f"4-D mesh: {len(space_time.cells):,} cells, {len(space_time.points):,} nodes, valid: "
             f"{check_valid_domain(space_time) or 'yes'}, boundary Euler characteristic "
             f"{boundary_euler_characteristic(space_time)}, mean radius ratio {quality.mean():.3f}", "",
             "| frame | section cells | section valid (flat pieces left aside) | section (ml) | 3-D mesh at R (ml) | "
             "ratio |", "|---|---|---|---|---|---|"]
    for frame, section in enumerate(frame_instants(space_time, shape.step, len(shape.frames))):
        alone = mesh(CINE / f"GPFile_{frame:03d}.txt", radius=radius, optimize=0).mesh
        problems = [p for p in check_valid_domain(section) if "flat cells" not in p]
        ratio = volume(section) / volume(alone)
        lines.append(f"| {frame} | {len(section.cells):,} | {problems or 'yes'} | {volume(section):.1f} | "
                     f"{volume(alone):.1f} | {ratio:.3f} |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        args.output.write_text(text)


if __name__ == "__main__":
    main()
