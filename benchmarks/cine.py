#!/usr/bin/env python
"""Every frame of a cardiac cycle meshed as ``bitemesh mesh GPFile_NNN.txt`` meshes it (no flags), measured against
the guide points and against biv-me's own fitted surfaces of the same frame (``benchmarks/heart_measures.py``).

The data: ``../shared/data/bivme_patient1_cine`` (biv-me patient1, 25 frames, with biv-me's fits), or $BITEMESH_DATA.
``--variants`` adds the classes of variation of ``tests/cardiac_variants.py`` built on chosen frames (open arcs,
shifted slices, frames merged into one file, sparser and denser exports); ``--gpfile PATH[:FRAME][@MODEL]`` adds
any other GPFile (another patient's, another tool's export), measured against its guide points and, given biv-me's
fit of it (MODEL, its control points ``*_model_frame_NNN.txt``) and ``--bivme-model`` (biv-me's ``src/model``
folder, not shipped), against biv-me's surfaces of that fit.

Usage (from the repository root)::

    python benchmarks/cine.py                              # all 25 frames
    python benchmarks/cine.py --frames 0 8 16 --variants   # three frames, and the variants of frame 0
    python benchmarks/cine.py --gpfile other/GPFile_000.txt:0 --frames
    python benchmarks/cine.py --frames --bivme-model biv-me/src/model --gpfile P/GPFile_000.txt:0@P/M_000.txt
        # P: biv-me/tests/test_data/patient_1_gpdata, M: reference_model/patient_1_gpdata_model_frame
    python benchmarks/cine.py --output benchmarks/cine.md
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))
sys.path.insert(0, str(HERE.parent))

from bitemesh.meshing import mesh
from bitemesh.options import parse_option
from bitemesh.core.errors import BitemeshError
from bitemesh.io import read_labelled_points
from heart_measures import measure_heart

from tests.cardiac_variants import CLASSES, class_file, read_surface


def cine_folder() -> Path:
    root = Path(os.environ.get("BITEMESH_DATA", HERE.parent.parent / "shared" / "data"))
    folder = root / "bivme_patient1_cine"
    if not (folder / "guidepoints" / "GPFile_000.txt").is_file():
        raise SystemExit(f"no guide points in {folder}")
    return folder


def reference(folder: Path, frame: int) -> dict:
    """biv-me's fitted surfaces of ``frame``: name -> (vertices, triangles)."""
    return {name: read_surface(folder / "fitted" / f"patient1_{name}_{frame:03d}.vtk")
            for name in ("EPICARDIAL", "LV_ENDOCARDIAL", "RV_ENDOCARDIAL")}


#: biv-me's surfaces as ranges of its subdivided model's triangles (ETIndicesSorted.txt, 0-based, inclusive):
#: BiventricularModel.surface_start_end, LV endocardium, RV septum and RV free wall, epicardium.
BIVME_TRIANGLES = {"LV_ENDOCARDIAL": ((0, 3071),), "RV_ENDOCARDIAL": ((3072, 4479), (4480, 6751)),
                   "EPICARDIAL": ((6752, 11615),)}


def model_surfaces(model: Path, control_points: Path) -> dict:
    """biv-me's fitted surfaces from a fit's (388, 3) control points and biv-me's model folder (its subdivision basis
    ``basis_matrix_sparse.mat``, 5,810 x 388, and triangles ``ETIndicesSorted.txt``): name -> (vertices, triangles)."""
    from scipy.io import loadmat
    vertices = loadmat(model / "basis_matrix_sparse.mat")["S"] @ np.loadtxt(control_points, delimiter=",",
                                                                           skiprows=1)[:, :3]
    triangles = np.loadtxt(model / "ETIndicesSorted.txt", dtype=np.int64) - 1
    surfaces = {}
    for name, ranges in BIVME_TRIANGLES.items():
        mine = np.vstack([triangles[first:last + 1] for first, last in ranges])
        used, renumbered = np.unique(mine, return_inverse=True)
        surfaces[name] = (np.asarray(vertices)[used], renumbered.reshape(mine.shape))
    return surfaces


def run_case(name: str, path: Path, frame=None, surfaces=None, options=None) -> dict:
    """Mesh ``path`` as bitemesh mesh does with no flag but ``--frame`` (and ``options``, names of bitemesh mesh's
    flags); its measures against the guide points the mesh was made from (short-axis slices moved where the
    registration moved them), or its refusal."""
    options = {**(options or {}), **({} if frame is None else {"frame": frame})}
    clock = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = mesh(path, options)
    except BitemeshError as error:
        return {"name": name, "refused": str(error), "seconds": time.perf_counter() - clock}
    seconds = time.perf_counter() - clock
    points, labels, slices = read_labelled_points(path, frame=frame)
    for number, shift in getattr(result.function, "shifts", {}).items():
        points[slices == number] += shift
    base = result.function.base
    row = measure_heart(result.mesh, points, labels, surfaces, None if base is None else base.below)
    row.update(name=name, seconds=seconds, notes=result.notes, warnings=[str(w.message) for w in caught])
    return row


def line(row: dict) -> str:
    """One markdown row."""
    if "refused" in row:
        return f"| {row['name']} | refused: {row['refused'][:160]} |" + " |" * 17
    surfaces = row.get("surfaces", {})
    both = " / ".join(f"{surfaces[name][0]:.2f}, {surfaces[name][1]:.2f}" if name in surfaces else "-"
                      for name in ("EPICARDIAL", "LV_ENDOCARDIAL", "RV_ENDOCARDIAL"))
    valves = " / ".join(f"{row[valve]:.1f}" if valve in row else "-"
                        for valve in ("MITRAL_VALVE", "TRICUSPID_VALVE", "AORTA_VALVE", "PULMONARY_VALVE"))
    volumes = f"{row['LV_ENDO_ml']:.0f} / {row['RV_ENDO_ml']:.0f}"
    offsets = f"{row['lv_offset']:+.2f}"
    if "bivme_LV_ENDO_ml" in row:
        volumes += f" ({row['bivme_LV_ENDO_ml']:.0f} / {row['bivme_RV_ENDO_ml']:.0f})"
        offsets += f" / {row['bivme_lv_offset']:+.2f}"
    flags = "; ".join(text.split(":")[0][:60] for text in row["warnings"])
    peer = f"{row['bivme_wall_mean']:.2f} / {row['bivme_wall_p95']:.2f}" if "bivme_wall_mean" in row else "-"
    return (f"| {row['name']} | {row['cells']:,} | {'yes' if row['valid'] else 'NO'} | {row['components']} | "
            f"{row['boundaries']} | {row['euler']} | {row['lips_mm']:.0f} | {row['wall_mean']:.2f} / "
            f"{row['wall_p95']:.2f} / "
            f"{row['wall_max']:.1f} | {peer} | {valves} | {both} | {row.get('to_bivme', np.nan):.2f} / "
            f"{row.get('from_bivme', np.nan):.2f} | {row.get('to_bivme_deep', np.nan):.2f} | "
            f"{row.get('to_bivme_near_data', np.nan):.2f} | "
            f"{row['myocardium_ml']:.0f} | {volumes} | {offsets} | {row['seconds']:.1f} | {flags} |")


HEADER = ("| case | cells | valid | parts | boundaries | Euler | hole lips (mm) | "
          "wall guide points mean / 95 % / max (mm) | "
          "biv-me's fit: wall guide points mean / 95 % (mm) | valves MV / TV / AV / PV max (mm) | "
          "biv-me EPI / LV / RV: ref->mesh, mesh->ref (mm) | mesh->biv-me / biv-me->mesh, mean of 3 (mm) | "
          "mesh->biv-me more than 10 mm below the base (mm) | the same within 1 mm of a wall guide point (mm) | "
          "myocardium (ml) | "
          "LV / RV cavity (ml) (biv-me) | LV cavity outward of its guide points: mesh / biv-me (mm) | time (s) | "
          "warnings |\n" + "|---" * 19 + "|")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="*", default=None, help="frames of the cine (default all)")
    parser.add_argument("--variants", action="store_true", help="the classes of variation on the first frame given")
    parser.add_argument("--classes", nargs="*", default=None, help="only these classes of variation")
    parser.add_argument("--gpfile", action="append", default=[],
                        help="another GPFile, PATH[:FRAME][@MODEL] (MODEL: biv-me's control points of its fit)")
    parser.add_argument("--bivme-model", type=Path, help="biv-me's src/model folder, to read MODEL")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="an option of bitemesh mesh for every case (e.g. slice_shifts=none)")
    parser.add_argument("--output", type=Path, help="write the table (markdown) here too")
    args = parser.parse_args(argv)
    options = {}
    for text in args.set:
        name, _, value = text.partition("=")
        options[name] = parse_option(name, value, "--set")
    folder = cine_folder()
    frames = list(range(25)) if args.frames is None else args.frames
    rows = []
    print(HEADER, flush=True)
    for frame in frames:
        path = folder / "guidepoints" / f"GPFile_{frame:03d}.txt"
        rows.append(run_case(f"frame {frame}", path, surfaces=reference(folder, frame), options=options))
        print(line(rows[-1]), flush=True)
    if args.variants:
        base = frames[0] if frames else 0
        with tempfile.TemporaryDirectory() as scratch:
            for name in args.classes or CLASSES:
                path, frame = class_file(folder / "guidepoints", base, name, scratch)
                rows.append(run_case(f"frame {base}, {name}", path, frame, reference(folder, base), options))
                print(line(rows[-1]), flush=True)
    for text in args.gpfile:
        text, _, model = text.partition("@")
        path, _, frame = text.partition(":")
        surfaces = model_surfaces(args.bivme_model, Path(model)) if model and args.bivme_model else None
        rows.append(run_case(f"{Path(path).parent.name}/{Path(path).name}" + (f" frame {frame}" if frame else ""),
                             Path(path), float(frame) if frame else None, surfaces, options))
        print(line(rows[-1]), flush=True)
    if args.output:
        args.output.write_text(HEADER + "\n" + "\n".join(line(row) for row in rows) + "\n")


if __name__ == "__main__":
    main()
