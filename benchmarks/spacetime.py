#!/usr/bin/env python
"""The beating heart as one 4-D space-time mesh (issue 36): biv-me patient1's cine through the front door,
``bitemesh.mesh(frames, space_time=1)`` as ``bitemesh mesh GPFile_*.txt --space-time`` runs it, each frame's instant
cut out of it and measured against the 3-D mesh of that frame at the same R (the 4-D mesh relaxed, the default;
each frame's 3-D mesh the plain method: the MeshOptimizer changes a volume by under 0.1 %).

Usage (from the repository root)::

    python benchmarks/spacetime.py --radius 8 --output benchmarks/spacetime.md --keep /tmp/cycle
    python benchmarks/spacetime.py --frames 8 --radius 6
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))

from bitemesh.core.mesh.quality import radius_ratio  # noqa: E402
from bitemesh.core.mesh.simplicial import signed_measures  # noqa: E402
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain  # noqa: E402
from bitemesh.io import write_mesh, write_time_series  # noqa: E402
from bitemesh.meshing import instants, mesh  # noqa: E402

CINE = HERE.parent.parent / "shared" / "data" / "bivme_patient1_cine" / "guidepoints"


def volume(cells_mesh) -> float:
    return float(signed_measures(cells_mesh.points, cells_mesh.cells).sum()) / 1000.0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=25, help="the first N frames of the cycle")
    parser.add_argument("--radius", type=float, default=None, help="R (mm); default the front door's")
    parser.add_argument("--output", type=Path, help="the Markdown table to write")
    parser.add_argument("--keep", type=Path, help="a folder to write cycle.npz and its instants (cycle.pvd) into")
    args = parser.parse_args(argv)
    paths = [CINE / f"GPFile_{frame:03d}.txt" for frame in range(args.frames)]
    clock = time.perf_counter()
    result = mesh(paths, space_time=1, **({"radius": args.radius} if args.radius else {}))
    seconds = time.perf_counter() - clock
    space_time, radius = result.mesh, result.radius
    sections = instants(result)
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
        write_mesh(space_time, args.keep / "cycle.npz")
        write_time_series(args.keep / "cycle.pvd", sections)
    quality = radius_ratio(space_time.points, space_time.cells)
    lines = [f"Space-time heart: {args.frames} frames, R = {radius:.3g} mm, {result.function.step:.3g} mm of time a "
             f"frame; {seconds:.0f} s in all ({', '.join(f'{k} {v:.0f} s' for k, v in result.seconds.items())})",
             f"4-D mesh: {len(space_time.cells):,} cells, {len(space_time.points):,} nodes, valid: "
             f"{check_valid_domain(space_time) or 'yes'}, boundary Euler characteristic "
             f"{boundary_euler_characteristic(space_time)}, mean radius ratio {quality.mean():.3f}", "",
             "| frame | instant's cells | instant valid (flat pieces left aside) | instant (ml) | 3-D mesh at R (ml) "
             "| ratio |", "|---|---|---|---|---|---|"]
    for frame, (path, section) in enumerate(zip(paths, sections)):
        # the frame's own mesh at that R, kept where its fidelity check would refuse it (frame 15 at 8 mm: 8 guide
        # points of a contradicted slice beyond R + 3 noise): its volume is what the instant is measured against
        alone = mesh(path, radius=radius, optimize=0, allow_unfaithful=1).mesh
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
