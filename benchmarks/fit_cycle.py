#!/usr/bin/env python
"""The elastic template over a cardiac cycle: biv-me patient1's frame 0 meshed with the defaults (the template), then
``bitemesh.fit_cycle`` over all 25 frames (each from the last, one connectivity), every frame measured as
``benchmarks/cine.py`` measures a mesh (the guide points, their slices moved where the fit's registration moved
them, biv-me's own fitted surfaces and cavity volumes of the same frame) plus the cells' quality.  The baseline
in the same run: meshing frame 0 from its guide points.

Usage (from the repository root)::

    python benchmarks/fit_cycle.py --output benchmarks/fit_cycle.md
    python benchmarks/fit_cycle.py --frames 0 4 8       # a shorter cycle
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))
sys.path.insert(0, str(HERE.parent))

from bitemesh.core.sources.contours.base import annulus_surface  # noqa: E402
from bitemesh.core.sources.contours.cardiac import BIVME_SURFACES, canonical_labels  # noqa: E402
from bitemesh.core.sources.contours.registration import registered  # noqa: E402
from bitemesh.core.sources.contours.slices import slice_planes  # noqa: E402
from bitemesh.fitting import fit_cycle, frame_fit_row  # noqa: E402
from bitemesh.io import read_labelled_points  # noqa: E402
from bitemesh.meshing import mesh  # noqa: E402
from cine import cine_folder, reference  # noqa: E402
from heart_measures import measure_heart  # noqa: E402

HEADER = ("| frame | fit (s) | rounds | wall guide points mean / 95 % (mm) | biv-me's fit: mean / 95 % (mm) | "
          "mesh -> biv-me / biv-me -> mesh (mm) | the same more than 10 mm below the base (mm) | LV ml (biv-me) | "
          "LV cavity outward of its guide points: mesh / biv-me (mm) | RV ml (biv-me) | myocardium ml | "
          "min dihedral (deg) | min radius ratio | valid |\n" + "|---" * 14 + "|")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="*", default=None, help="frames of the cine (default all)")
    parser.add_argument("--output", type=Path, help="write the table (markdown) here too")
    args = parser.parse_args(argv)
    folder = cine_folder()
    frames = list(range(25)) if args.frames is None else args.frames
    paths = [folder / "guidepoints" / f"GPFile_{frame:03d}.txt" for frame in frames]
    clock = time.perf_counter()
    template = mesh(paths[0]).mesh
    meshing = time.perf_counter() - clock
    cycle = fit_cycle(template, paths)
    lines, bivme = [], []
    for frame, path, fitted in zip(frames, paths, cycle.fits):
        points, labels, slices = read_labelled_points(path)
        *_, registration = registered(points, canonical_labels(labels)[0], slices, BIVME_SURFACES)
        for number, shift in registration.shifts.items():   # every point measured where the fit took its slice
            points[slices == number] += shift
        base, _ = annulus_surface(points, canonical_labels(labels)[0], slices, slice_planes(points, slices))
        row = {**measure_heart(fitted.mesh, points, labels, reference(folder, frame), base.below),
               **frame_fit_row(fitted)}
        bivme.append(row["bivme_LV_ENDO_ml"])
        lines.append(f"| {frame} | {row['seconds']:.1f} | {row['rounds']} | {row['wall_mean']:.2f} / "
                     f"{row['wall_p95']:.2f} | {row['bivme_wall_mean']:.2f} / {row['bivme_wall_p95']:.2f} | "
                     f"{row['to_bivme']:.2f} / {row['from_bivme']:.2f} | {row['to_bivme_deep']:.2f} | "
                     f"{row['LV_ENDO_ml']:.0f} ({row['bivme_LV_ENDO_ml']:.0f}) | "
                     f"{row['lv_offset']:+.2f} / {row['bivme_lv_offset']:+.2f} | "
                     f"{row['RV_ENDO_ml']:.0f} ({row['bivme_RV_ENDO_ml']:.0f}) | "
                     f"{row['myocardium_ml']:.0f} | {row['min_dihedral']:.1f} | {row['min_radius_ratio']:.3f} | "
                     f"{'yes' if row['valid'] else 'NO'} |")
        print(lines[-1], flush=True)
    bivme = np.array(bivme)
    lv = cycle.volumes[:, 0]
    seconds = np.array([fitted.seconds for fitted in cycle.fits])
    summary = (f"\nTemplate: frame {frames[0]} meshed with the defaults, {len(template.cells):,} cells, "
               f"{meshing:.1f} s. Fit: {seconds.mean():.1f} s a frame on average ({seconds.max():.1f} s at most), "
               f"{seconds.mean() / meshing:.2f} x meshing the frame from its guide points in the same run.\n"
               f"LV volume against biv-me's: {100 * np.abs(lv / bivme - 1).max():.1f} % at most, "
               f"{100 * np.abs(lv / bivme - 1).mean():.1f} % on average. Ejection fraction: "
               f"{cycle.ejection_fraction:.1f} % (ED frame {frames[cycle.end_diastole]}, ES frame "
               f"{frames[cycle.end_systole]}); biv-me's: {100 * (bivme.max() - bivme.min()) / bivme.max():.1f} % "
               f"(ED frame {frames[int(np.argmax(bivme))]}, ES frame {frames[int(np.argmin(bivme))]}).\n")
    print(summary)
    if args.output:
        args.output.write_text(HEADER + "\n" + "\n".join(lines) + "\n" + summary)


if __name__ == "__main__":
    main()
