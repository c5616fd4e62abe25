#!/usr/bin/env python
"""The elastic template over a cardiac cycle: biv-me patient1's frame 0 meshed with the defaults (the template), then
``bitemesh.fit_cycle`` over all 25 frames (each from the last, one connectivity), every frame measured as
``benchmarks/cine.py`` measures a mesh (the guide points, their slices moved where the fit's registration moved
them, biv-me's own fitted surfaces and cavity volumes of the same frame) plus the cells' quality, and each frame's LV
volume against that of the frame meshed from its guide points alone (the mesher's own route, no template).  The baseline
in the same run: meshing frame 0 from its guide points.  ``--gpfile`` fits the same template in one step to another
patient's frame, measured against biv-me's fit of it (as ``benchmarks/cine.py`` reads one).

Usage (from the repository root)::

    python benchmarks/fit_cycle.py --output benchmarks/fit_cycle.md
    python benchmarks/fit_cycle.py --frames 0 4 8       # a shorter cycle
    python benchmarks/fit_cycle.py --bivme-model biv-me/src/model --gpfile P/GPFile_000.txt:0@P/M_000.txt
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

from bitemesh.core.errors import BitemeshError  # noqa: E402
from bitemesh.core.mesh.tags import enclosed_volume  # noqa: E402
from bitemesh.core.sources.contours.cardiac import BIVME_SURFACES, canonical_labels  # noqa: E402
from bitemesh.core.sources.contours.registration import registered  # noqa: E402
from bitemesh.fitting import fit, fit_cycle, frame_base, frame_fit_row  # noqa: E402
from bitemesh.io import read_labelled_points  # noqa: E402
from bitemesh.meshing import mesh  # noqa: E402
from cine import cine_folder, model_surfaces, reference  # noqa: E402
from heart_measures import measure_heart, tagged  # noqa: E402

HEADER = ("| frame | fit (s) | rounds | wall guide points mean / 95 % (mm) | biv-me's fit: mean / 95 % (mm) | "
          "mesh -> biv-me / biv-me -> mesh (mm) | mesh -> biv-me more than 10 mm below the base / there within 1 mm "
          "of a wall guide point (mm) | "
          "LV ml: fit / the frame meshed (biv-me) | "
          "LV cavity outward of its guide points: mesh / biv-me (mm) | RV ml (biv-me) | myocardium ml | "
          "min dihedral (deg) | min radius ratio | valid |\n" + "|---" * 14 + "|")


def measured_row(name: str, fitted, path: Path, frame, surfaces: dict | None, meshed: float = np.nan) -> tuple:
    """(the markdown row of one fit of the guide points at ``path`` (``frame`` of a GPFile holding several, or
    None), measured against biv-me's ``surfaces`` of them and the LV volume of the same data meshed, ``meshed``
    (ml); the row's measures)."""
    points, labels, slices = read_labelled_points(path, frame=frame)
    *_, registration = registered(points, canonical_labels(labels)[0], slices, BIVME_SURFACES)
    for number, shift in registration.shifts.items():   # every point measured where the fit took its slice
        points[slices == number] += shift
    base = frame_base(points, canonical_labels(labels)[0], slices)
    row = {**measure_heart(fitted.mesh, points, labels, surfaces, base.below), **frame_fit_row(fitted)}
    line = (f"| {name} | {row['seconds']:.1f} | {row['rounds']} | {row['wall_mean']:.2f} / "
            f"{row['wall_p95']:.2f} | {row['bivme_wall_mean']:.2f} / {row['bivme_wall_p95']:.2f} | "
            f"{row['to_bivme']:.2f} / {row['from_bivme']:.2f} | "
            f"{row['to_bivme_deep']:.2f} / {row['to_bivme_near_data']:.2f} | "
            f"{row['LV_ENDO_ml']:.0f} / {meshed:.0f} ({row['bivme_LV_ENDO_ml']:.0f}) | "
            f"{row['lv_offset']:+.2f} / {row['bivme_lv_offset']:+.2f} | "
            f"{row['RV_ENDO_ml']:.0f} ({row['bivme_RV_ENDO_ml']:.0f}) | "
            f"{row['myocardium_ml']:.0f} | {row['min_dihedral']:.1f} | {row['min_radius_ratio']:.3f} | "
            f"{'yes' if row['valid'] else 'NO'} |")
    return line, row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="*", default=None, help="frames of the cine (default all)")
    parser.add_argument("--gpfile", action="append", default=[],
                        help="another patient's GPFile the template is fitted to in one step, PATH[:FRAME]@MODEL "
                             "(MODEL: biv-me's control points of its fit of it)")
    parser.add_argument("--bivme-model", type=Path, help="biv-me's src/model folder, to read MODEL")
    parser.add_argument("--output", type=Path, help="write the table (markdown) here too")
    args = parser.parse_args(argv)
    folder = cine_folder()
    frames = list(range(25)) if args.frames is None else args.frames
    paths = [folder / "guidepoints" / f"GPFile_{frame:03d}.txt" for frame in frames]
    clock = time.perf_counter()
    template = mesh(paths[0]).mesh
    meshing = time.perf_counter() - clock
    cycle = fit_cycle(template, paths)
    meshed = [template] + [mesh(path).mesh for path in paths[1:]]   # the yardstick from the data alone
    meshed = np.array([enclosed_volume(heart.points, tagged(heart, ("LV_ENDO",))) / 1000 for heart in meshed])
    lines, bivme = [], []
    for frame, path, fitted, alone in zip(frames, paths, cycle.fits, meshed):
        line, row = measured_row(str(frame), fitted, path, None, reference(folder, frame), alone)
        bivme.append(row["bivme_LV_ENDO_ml"])
        lines.append(line)
        print(line, flush=True)
    others = []
    for text in args.gpfile:
        text, _, model = text.partition("@")
        path, _, frame = text.partition(":")
        frame = int(frame) if frame else None
        name = f"{Path(path).parent.name}/{Path(path).name}" + ("" if frame is None else f" frame {frame}")
        try:
            fitted = fit(template, path, frame=frame)
        except BitemeshError as error:
            others.append(f"| {name} | refused: {str(error)[:200]} |" + " |" * 12)
        else:
            alone = mesh(path, {} if frame is None else {"frame": frame}).mesh
            others.append(measured_row(name, fitted, Path(path), frame, model_surfaces(args.bivme_model, Path(model)),
                                       enclosed_volume(alone.points, tagged(alone, ("LV_ENDO",))) / 1000)[0])
        print(others[-1], flush=True)
    bivme = np.array(bivme)
    lv = cycle.volumes[:, 0]
    seconds = np.array([fitted.seconds for fitted in cycle.fits])
    summary = (f"\nTemplate: frame {frames[0]} meshed with the defaults, {len(template.cells):,} cells, "
               f"{meshing:.1f} s. Fit: {seconds.mean():.1f} s a frame on average ({seconds.max():.1f} s at most), "
               f"{seconds.mean() / meshing:.2f} x meshing the frame from its guide points in the same run.\n"
               f"LV volume against biv-me's: {100 * np.abs(lv / bivme - 1).max():.1f} % at most, "
               f"{100 * np.abs(lv / bivme - 1).mean():.1f} % on average; against each frame meshed from its "
               f"guide points: {100 * np.abs(lv / meshed - 1).max():.1f} % at most, "
               f"{100 * np.abs(lv / meshed - 1).mean():.1f} % on average (biv-me's against the same: "
               f"{100 * np.abs(bivme / meshed - 1).max():.1f} % at most). Ejection fraction: "
               f"{cycle.ejection_fraction:.1f} % (ED frame {frames[cycle.end_diastole]}, ES frame "
               f"{frames[cycle.end_systole]}); biv-me's: {100 * (bivme.max() - bivme.min()) / bivme.max():.1f} % "
               f"(ED frame {frames[int(np.argmax(bivme))]}, ES frame {frames[int(np.argmin(bivme))]}).\n")
    print(summary)
    if others:
        summary += ("\nThe frame-0 template fitted in one step to other patients' frames (biv-me's test patients, not "
                    "shipped), each against biv-me's fit of it:\n\n" + HEADER + "\n" + "\n".join(others) + "\n")
    if args.output:
        args.output.write_text(HEADER + "\n" + "\n".join(lines) + "\n" + summary)


if __name__ == "__main__":
    main()
