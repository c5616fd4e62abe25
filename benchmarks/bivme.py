#!/usr/bin/env python
"""Real cardiac contours: the biv-me example patient1 (GPFile_000.txt) meshed as the two-cavity myocardium.

Prints, for one configuration (default: the library's defaults) or for every candidate implicit method
(``--candidates``):

- guide points -> mesh boundary: for each contour point, the distance to the boundary triangles of its own surface
  (EPI, LV_ENDO or RV_ENDO; a boundary triangle belongs to the surface whose implicit is active at its centroid),
  mean and max, over the points below the base plane (the domain cannot reach the others) and over all;
- fitted biv-me surfaces -> mesh boundary: mean (and max) distance from the vertices of patient1_*_000.vtk below the
  base plane to the boundary triangles of the same surface;
- leave-one-slice-out: each slice's contour points to the zero level of the surfaces fitted without that slice
  (how well the implicit interpolates between slices), mean and max;
- myocardial volume, connected components, boundary components and Euler characteristic, whether each cavity is
  open (the deepest point of each cavity below the base plane lies outside the mesh), time and quality.

Distances are exact point-to-triangle distances (the nearest of the 24 triangles with the nearest centroids).

Usage (from the repository root)::

    python benchmarks/bivme.py                         # defaults, 136,000 cells
    python benchmarks/bivme.py --cells 10000
    python benchmarks/bivme.py --cells 155000 --seeds 5 [--no-optimize]   # one line per seed (the demo's setting)
    python benchmarks/bivme.py --candidates --cells 30000 --output benchmarks/bivme-candidates.md

The data folder is ../shared/data/bivme_patient1 beside the clone, or $BITEMESH_DATA/bivme_patient1, or
the copy shipped in the package (filters/bitemesh/data/bivme_patient1, without the reference surfaces).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))
sys.path.insert(0, str(HERE.parent))

from bitemesh.core.sources.contours.cardiac import BIVME_DEFAULT_DOMAIN
from bitemesh.core.sources.contours.fit import labelled_implicit
from bitemesh.core.parameters import KERNELS
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.sources.contours.surface_fit import fit_contour_rbf
from bitemesh.core.sources.contours.cardiac import default_surfaces
from bitemesh.core.sources.contours.csg import domain_names, parse_domain
from bitemesh.core.sources.contours.fit import SURFACE_BAND, SURFACE_LEVELS
from bitemesh.core.sources.contours.slices import contour_normals, slice_planes
from bitemesh.core.errors import BitemeshWarning
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.implicit.mpu import fit_mpu
from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters
from bitemesh.core.sources.source import Frame, Source
from bitemesh.core.steps.spine import mesh_source
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain, count_boundary_components
from bitemesh.core.mesh.topology import connected_components
from bitemesh.core.mesh.quality import dihedral_angles
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.io import read_labelled_points
from scipy.spatial import cKDTree
from tests.cardiac_variants import read_surface

REFERENCES = {"EPI": "patient1_EPICARDIAL_000.vtk", "LV_ENDO": "patient1_LV_ENDOCARDIAL_000.vtk",
              "RV_ENDO": "patient1_RV_ENDOCARDIAL_000.vtk"}
CAVITIES = ("LV_ENDO", "RV_ENDO")


def data_folder() -> Path:
    candidates = [Path(os.environ["BITEMESH_DATA"]) / "bivme_patient1"] if "BITEMESH_DATA" in os.environ else []
    candidates += [HERE.parent.parent / "shared" / "data" / "bivme_patient1",
                   HERE.parent / "filters" / "bitemesh" / "data" / "bivme_patient1"]
    for folder in candidates:
        if (folder / "GPFile_000.txt").is_file():
            return folder
    raise SystemExit(f"no GPFile_000.txt in {', '.join(map(str, candidates))}")


# --- geometry helpers --------------------------------------------------------------------------------------------

def point_triangle_distance(p, a, b, c):
    """(m,) distance from points p to triangles (a, b, c), all (m, 3): Ericson, Real-Time Collision Detection 5.1.5."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = 1.0 / (va + vb + vc)
        v, w = vb * denominator, vc * denominator
        closest = a + ab * v[:, None] + ac * w[:, None]                                   # inside the face
        t_ab, t_ac = d1 / (d1 - d3), d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        regions = [
            (d1 <= 0) & (d2 <= 0), a,
            (d3 >= 0) & (d4 <= d3), b,
            (d6 >= 0) & (d5 <= d6), c,
            (vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None],
            (vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None],
            (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + (c - b) * t_bc[:, None],
        ]
    done = np.zeros(len(p), bool)
    result = closest.copy()
    for mask, point in zip(regions[::2], regions[1::2]):
        take = mask & ~done
        result[take] = point[take]
        done |= take
    return np.linalg.norm(p - result, axis=1)


def distance_to_triangles(points, vertices, triangles, candidates: int = 24):
    """(m,) distance from each point to the nearest of the triangles (inf if there are none)."""
    if len(triangles) == 0:
        return np.full(len(points), np.inf)
    k = min(candidates, len(triangles))
    _, near = cKDTree(vertices[triangles].mean(axis=1)).query(points, k=k)
    near = near.reshape(len(points), k)
    corners = vertices[triangles[near.ravel()]]
    repeated = np.repeat(points, k, axis=0)
    return point_triangle_distance(repeated, corners[:, 0], corners[:, 1], corners[:, 2]).reshape(-1, k).min(axis=1)


def located(mesh, points, candidates: int = 32) -> np.ndarray:
    """(m,) True for the points inside a tetrahedron of ``mesh`` (among the cells with the nearest centroids)."""
    corners = mesh.points[mesh.cells]
    k = min(candidates, len(corners))
    _, near = cKDTree(corners.mean(axis=1)).query(points, k=k)
    near = near.reshape(len(points), k)
    origin = corners[near, 0]                                            # (m, k, 3)
    edges = (corners[near, 1:] - origin[:, :, None]).transpose(0, 1, 3, 2)   # (m, k, 3, 3)
    local = np.linalg.solve(edges, (points[:, None] - origin)[..., None])[..., 0]
    return ((local >= -1e-9).all(axis=2) & (local.sum(axis=2) <= 1 + 1e-9)).any(axis=1)


def base_opening(mesh, function, name, lower, upper, depth=1.0, spacing=1.0) -> float:
    """Fraction of the cavity's section ``depth`` below the base (where its implicit exceeds 1 mm) that lies
    outside the mesh: about 1 when the cavity opens through the base, about 0 under a lid."""
    axes = [np.arange(lo, hi, spacing) for lo, hi in zip(lower, upper)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    grid = grid[np.abs(function.base.below(grid) - depth) < spacing / 2]
    inside = grid[function.surfaces[name](grid) > 1.0]
    return float(np.mean(~located(mesh, inside))) if len(inside) else float("nan")


def height(function, x):
    """About the signed height above the base (> 0: cut away)."""
    if function.base is None:
        return np.full(len(x), -np.inf)
    return -function.base.below(x)


def deepest_point(surface, base, lower, upper, spacing=1.5):
    """The point of largest implicit value of a cavity, at least 5 mm below the base."""
    axes = [np.arange(lo, hi, spacing) for lo, hi in zip(lower, upper)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    if base is not None:
        nodes = nodes[base.below(nodes) > 5.0]
    values = surface(nodes)
    return nodes[int(np.argmax(values))], float(values.max())


# --- candidates --------------------------------------------------------------------------------------------------

def mpu_implicit(points, labels, slices, **options):
    """The library's pipeline with every surface reconstructed by MPU (fit_mpu) from the same in-plane normals and
    sampled on the same grids."""
    function, lower, upper = labelled_implicit(points, labels, slices=slices, **options)
    surfaces = {}
    for name, surface_points in function.points.items():
        normals = function.normals[name]
        good = np.isfinite(normals).all(axis=1)
        mpu = fit_mpu(surface_points[good], normals[good])
        grid = function.surfaces[name]
        step = grid.spacing[0]
        surfaces[name] = sample_function(mpu, grid.origin, grid.upper, step, exact_within=SURFACE_BAND * step,
                                         levels=SURFACE_LEVELS)
    return dataclasses.replace(function, surfaces=surfaces), lower, upper


def zero_level_distance(surface, points, iterations: int = 8):
    """Distance from points to the zero level of ``surface`` (an RBF with .gradient), by Newton projection."""
    x = points.copy()
    for _ in range(iterations):
        value, slope = surface(x), surface.gradient(x)
        step = (value / np.maximum(np.einsum("ij,ij->i", slope, slope), 1e-12))[:, None] * slope
        length = np.linalg.norm(step, axis=1, keepdims=True)
        x = x - step * np.minimum(1.0, 5.0 / np.maximum(length, 1e-12))   # at most 5 mm per step
    return np.linalg.norm(x - points, axis=1)


def leave_one_slice_out(points, labels, slices, options):
    """Per contour point of the used surfaces: distance to the surface refitted without the point's slice."""
    surfaces = default_surfaces(labels)
    tree = parse_domain(BIVME_DEFAULT_DOMAIN, surfaces)
    planes = slice_planes(points, slices)
    fit_options = {key: options[key] for key in ("kernel", "offset", "smoothing") if key in options}
    errors = []
    for name in domain_names(tree):
        members = np.isin(labels, surfaces[name])
        _, first = np.unique(points[members], axis=0, return_index=True)
        index = np.flatnonzero(members)[np.sort(first)]
        normals = contour_normals(points[index], slices[index], planes)
        for held in np.unique(slices[index]):
            keep = slices[index] != held
            rbf = fit_contour_rbf(points[index][keep], normals[keep], **fit_options)
            errors.append(zero_level_distance(rbf, points[index][~keep]))
    errors = np.concatenate(errors)
    return float(errors.mean()), float(np.percentile(errors, 95)), float(errors.max())


# --- one run -----------------------------------------------------------------------------------------------------

def measure(folder: Path, cells, options: dict, *, method: str = "rbf", loso: bool = False, seed: int = 0,
            optimize: bool = True, save=None, gpfile=None) -> dict:
    """One run on ``gpfile`` (default the folder's GPFile_000.txt); ``cells`` None: the library's default size."""
    points, labels, slices = read_labelled_points(gpfile or folder / "GPFile_000.txt")
    biting = BitingParameters(seed=seed) if cells is None else BitingParameters(cells=cells, seed=seed)
    clock = time.perf_counter()
    if method == "mpu":
        function, lower, upper = mpu_implicit(points, labels, slices, **options)
        fitted = time.perf_counter()
        result = mesh_source(Source(function, lower, upper, Frame.identity(3)), ImplicitParameters(), biting)
        meshing = sum(value for key, value in result.seconds.items() if not key.startswith("implicit"))
        seconds = {"fit": fitted - clock, "sampling": result.seconds["implicit sampling"], "meshing": meshing}
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BitemeshWarning)   # the handles are counted below
            result = run_labelled(points, labels, slices=slices, biting=biting,
                                           optimize=OptimizeParameters(optimize=int(optimize)), **options)
        function, lower, upper = result.function, result.function.lower, result.function.upper
        meshing = sum(value for key, value in result.seconds.items() if not key.startswith("implicit"))
        seconds = {"fit": result.seconds["implicit fit"], "sampling": result.seconds["implicit sampling"],
                   "meshing": meshing}
    radius = result.radius
    grid = result.implicit
    mesh = result.mesh
    if save:
        from bitemesh.io import write_mesh
        write_mesh(mesh, save)

    facets = boundary_facets(mesh.cells)
    facet_surface = function.active_surface(mesh.points[facets].mean(axis=1))
    names = function.names
    row = {"cells": len(mesh.cells), "radius": radius, "seconds": seconds, "grid": "x".join(map(str, grid.shape)),
           "min_wall": function.min_wall, "points": len(points), "fidelity": result.fidelity,
           "notes": result.notes}
    # guide points -> own surface
    guide_all, guide_below = [], []
    for name, surface_points in function.points.items():
        own = facets[facet_surface == names.index(name)]
        distance = distance_to_triangles(surface_points, mesh.points, own)
        guide_all.append(distance)
        guide_below.append(distance[height(function, surface_points) < 0])
    guide_all, guide_below = np.concatenate(guide_all), np.concatenate(guide_below)
    row.update(guide_mean=guide_below.mean(), guide_max=guide_below.max(), guide_p95=np.percentile(guide_below, 95),
               guide_below=len(guide_below), guide_total=len(guide_all), guide_all_mean=guide_all.mean(),
               guide_all_max=guide_all.max())
    # fitted biv-me surfaces -> own surface
    reference = {}
    for name, filename in REFERENCES.items():
        if name not in function.surfaces or not (folder / filename).is_file():
            continue
        vertices, _ = read_surface(folder / filename)
        vertices = vertices[height(function, vertices) < 0]
        own = facets[facet_surface == names.index(name)]
        distance = distance_to_triangles(vertices, mesh.points, own)
        reference[name] = (float(distance.mean()), float(distance.max()))
    row["reference"] = reference
    if reference:
        row["reference_mean"] = float(np.mean([value[0] for value in reference.values()]))
    # topology, cavities, quality
    row["volume"] = float(mesh.cell_data["Volume"].sum())
    row["components"] = int(connected_components(mesh.cells).max() + 1)
    row["boundaries"] = count_boundary_components(mesh)
    row["euler"] = boundary_euler_characteristic(mesh)
    row["valid"] = not check_valid_domain(mesh)
    row["open"], row["opening"] = {}, {}
    for name in CAVITIES:
        if name in function.surfaces:
            point, _ = deepest_point(function.surfaces[name], function.base, lower, upper)
            row["open"][name] = not located(mesh, point[None])[0]
            if function.base is not None:
                row["opening"][name] = base_opening(mesh, function, name, lower, upper)
    quality = mesh.cell_data["RadiusRatio"]
    row.update(q_mean=float(quality.mean()), q_min=float(quality.min()),
               dihedral_min=float(np.nanmin(dihedral_angles(mesh.points, mesh.cells))),
               base_counts={names[i]: int(np.sum(facet_surface == i)) for i in range(len(names))})
    if loso:
        row["loso"] = leave_one_slice_out(points, labels, slices, options)
    return row


def describe(row: dict) -> str:
    seconds = row["seconds"]
    reference = ", ".join(f"{name} mean {mean:.2f} max {peak:.2f} mm"
                          for name, (mean, peak) in row["reference"].items())
    if "reference_mean" in row:
        reference += f"; mean of the three {row['reference_mean']:.2f} mm"
    cavities = ", ".join(f"{name} {'yes' if value else 'NO'}" for name, value in row["open"].items())
    opening = ", ".join(f"{name} {value:.0%}" for name, value in row["opening"].items())
    lines = [
        (f"cells {row['cells']:,}  R {row['radius']:.3g} mm  min_wall {row['min_wall']:.3g} mm  grid {row['grid']}  "
         f"time fit {seconds['fit']:.1f} s + sampling {seconds['sampling']:.1f} s + meshing "
         f"{seconds['meshing']:.1f} s = {sum(seconds.values()):.1f} s"),
        (f"guide points below the base plane ({row['guide_below']} of {row['guide_total']}) -> own surface: mean "
         f"{row['guide_mean']:.3f} mm, 95 % {row['guide_p95']:.3f} mm, max {row['guide_max']:.3f} mm "
         f"(all points: mean {row['guide_all_mean']:.3f}, max {row['guide_all_max']:.3f} mm)"),
        f"fitted biv-me surfaces (vertices below the base plane) -> own surface: {reference}",
        (f"myocardial volume {row['volume'] / 1000:.1f} ml; components {row['components']}; boundary surfaces "
         f"{row['boundaries']}, Euler characteristic {row['euler']}; valid {row['valid']}; cavities open: "
         f"{cavities}; cavity section 1 mm below the base plane outside the mesh: {opening}"),
        (f"quality: mean radius ratio {row['q_mean']:.3f}, min {row['q_min']:.3f}, min dihedral "
         f"{row['dihedral_min']:.1f} deg; boundary triangles per surface {row['base_counts']}"),
    ]
    if "loso" in row:
        lines.append(f"leave-one-slice-out: mean {row['loso'][0]:.2f} mm, 95 % {row['loso'][1]:.2f} mm, "
                     f"max {row['loso'][2]:.2f} mm")
    return "\n".join(lines)


def seed_table(rows: list) -> str:
    """One markdown line per seed: topology, distances to the guide points, volume, quality, time."""
    lines = ["| seed | cells | Euler char. | boundaries | components | guide mean / max (mm) | biv-me surfaces (mm) "
             "| volume (ml) | mean Q | min dihedral | time (s) |", "|" + "---|" * 11]
    for seed, row in enumerate(rows):
        lines.append(f"| {seed} | {row['cells']:,} | {row['euler']} | {row['boundaries']} | {row['components']} | "
                     f"{row['guide_mean']:.3f} / {row['guide_max']:.2f} | {row.get('reference_mean', np.nan):.2f} | "
                     f"{row['volume'] / 1000:.1f} | "
                     f"{row['q_mean']:.3f} | {row['dihedral_min']:.1f} | {sum(row['seconds'].values()):.0f} |")
    return "\n".join(lines)


def variant_table(folder: Path, shipped: Path, seed: int = 0) -> str:
    """One markdown line per variant of tests/cardiac_variants.py, meshed with the defaults (R = 2 mm, the
    MeshOptimizer on)."""
    from tests.cardiac_variants import VARIANTS, variant_file
    import tempfile
    lines = ["| variant | points | cells | fit + sampling (s) | meshing (s) | total (s) | guide -> boundary mean / "
             "95 % (mm) | guide -> own surface mean / 95 % (mm) | volume (ml) | vs shipped | Euler | cavities open | "
             "mean Q | min dihedral (deg) | derived / noted |", "|" + "---|" * 15]
    full = None
    with tempfile.TemporaryDirectory() as scratch:
        for name in VARIANTS:
            path = variant_file(shipped, name, scratch)
            try:
                row = measure(folder, None, {}, seed=seed, gpfile=path)
            except Exception as error:   # a refusal is a result too
                count = sum(1 for _ in open(path)) - 1
                lines.append(f"| {name} | {count:,} | refused: {str(error)[:150]}... |" + " |" * 12)
                continue
            full = row["volume"] if name == "shipped" else full
            s, fidelity = row["seconds"], row["fidelity"]
            noted = "; ".join(note.split(":")[0] for note in row["notes"] if not note.startswith("cardiac contours"))
            lines.append(
                f"| {name} | {row['points']:,} | {row['cells']:,} | {s['fit'] + s['sampling']:.1f} | "
                f"{s['meshing']:.1f} | {sum(s.values()):.1f} | {fidelity.to_boundary_mean:.2f} / "
                f"{fidelity.to_boundary_p95:.2f} | {row['guide_mean']:.2f} / {row['guide_p95']:.2f} | "
                f"{row['volume'] / 1000:.1f} | {row['volume'] / full - 1:+.1%} | {row['euler']} | "
                f"{', '.join(n for n, is_open in row['open'].items() if is_open) or 'none'} | {row['q_mean']:.3f} | "
                f"{row['dihedral_min']:.1f} | {noted} |")
            print(lines[-1], flush=True)
    return "\n".join(lines)


#: implicit methods and their tuning (the library's defaults: linear kernel, offset 4 mm, min_wall 2.5 mm, valve
#: outlets), then ablations of the domain's construction
CANDIDATES = {
    "rbf linear (biharmonic, Carr 2001), offset 4": {"kernel": "linear", "offset": 4.0},
    "rbf linear, offset 2": {"kernel": "linear", "offset": 2.0},
    "rbf linear, offset 6": {"kernel": "linear", "offset": 6.0},
    "rbf linear, offset 4, smoothing 1e-4": {"kernel": "linear", "offset": 4.0, "smoothing": 1e-4},
    "rbf cubic (triharmonic), offset 4": {"kernel": "cubic", "offset": 4.0},
    "rbf cubic, offset 2": {"kernel": "cubic", "offset": 2.0},
    "rbf thin plate, offset 4": {"kernel": "thin_plate", "offset": 4.0},
    "mpu (Ohtake 2003), in-plane normals": {"method": "mpu"},
    "ablation: min_wall 0": {"min_wall": 0.0},
    "ablation: no valve outlets": {"outlets": {}},
}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", type=int, default=136_000)
    parser.add_argument("--candidates", action="store_true", help="measure every candidate implicit method")
    parser.add_argument("--variants", action="store_true", help="every variant of tests/cardiac_variants.py at the "
                        "default size, one table")
    parser.add_argument("--loso", action="store_true", help="also the leave-one-slice-out test (RBF only)")
    parser.add_argument("--kernel", default=None, choices=KERNELS)
    parser.add_argument("--offset", type=float, default=None)
    parser.add_argument("--smoothing", type=float, default=None)
    parser.add_argument("--base-offset", type=float, default=None)
    parser.add_argument("--min-wall", type=float, default=None)
    parser.add_argument("--seed", type=int, default=0, help="seed of the biting")
    parser.add_argument("--seeds", type=int, help="one line per seed 0 .. SEEDS-1 (topology, distances, quality)")
    parser.add_argument("--optimize", action=argparse.BooleanOptionalAction, default=True,
                        help="run the MeshOptimizer, as every interface does by default (--no-optimize: the plain "
                        "method)")
    parser.add_argument("--save", help="write the mesh here (.vtu)")
    parser.add_argument("--output", help="also write the report (markdown) here")
    args = parser.parse_args(argv)
    folder = data_folder()
    out = [f"# bivme_patient1: {folder}", ""]
    if args.variants:
        text = f"## variants of GPFile_000.txt, default size, seed {args.seed}\n\n" + variant_table(
            folder, folder / "GPFile_000.txt", args.seed) + "\n"
        print(text)
        out.append(text)
    elif args.candidates:
        for title, options in CANDIDATES.items():
            options = dict(options)
            method = options.pop("method", "rbf")
            loso = args.loso and method == "rbf" and not title.startswith("ablation")
            row = measure(folder, args.cells, options, method=method, loso=loso)
            text = f"## {title}\n\n```\n{describe(row)}\n```\n"
            print(text, flush=True)
            out.append(text)
    else:
        options = {}
        for key in ("kernel", "offset", "smoothing", "base_offset", "min_wall"):
            if getattr(args, key) is not None:
                options[key] = getattr(args, key)
        title = f"{options}{'' if args.optimize else ' plain (--no-optimize)'}, {args.cells:,} cells asked"
        if args.seeds:
            rows = [measure(folder, args.cells, options, seed=seed, optimize=args.optimize)
                    for seed in range(args.seeds)]
            text = f"## {title}, seeds 0-{args.seeds - 1}\n\n{seed_table(rows)}\n"
        else:
            row = measure(folder, args.cells, options, loso=args.loso, save=args.save, seed=args.seed,
                          optimize=args.optimize)
            text = f"## {title}\n\n```\n{describe(row)}\n```\n"
        print(text)
        out.append(text)
    if args.output:
        Path(args.output).write_text("\n".join(out))


if __name__ == "__main__":
    main()
