#!/usr/bin/env python
"""bitemesh (without and with the MeshOptimizer) beside gmsh and TetGen, side by side in one run (issue #5).

For each shape (unit sphere; torus R = 1, r = 0.4, as in ``bitemesh.core.shapes``) at about 10,000 tetrahedra:

* bitemesh: noisy scattered surface points with normals (``run_benchmarks.make_input``, seed 0), then
  ``pipeline.run`` with default parameters and ``BitingParameters(cells=N)``, once with ``OptimizeParameters()``
  (off) and once with ``OptimizeParameters(optimize=1)``.  The time is the whole ``run`` (implicit fit included).
* gmsh (Python API, if importable): the exact shape from OpenCASCADE (``occ.addSphere`` / ``occ.addTorus``),
  default 3D algorithm (Delaunay), ``Mesh.Optimize = 1``, ``Mesh.OptimizeNetgen = 1``.  The mesh size is
  calibrated for about N tets (untimed calibration runs, size scaled by (n / N)^(1/3)); the timed run is the last.
* TetGen (the ``tetgen`` package, if importable): a triangulated surface built here (geodesic icosphere / a
  (u, v) torus grid) at an edge length matched to the volume mesh, then ``-pq1.2a<vol>`` (order 1, minratio 1.2,
  maxvolume calibrated for about N tets the same way).  The time is ``tetrahedralize`` only (surface excluded).

Every mesh is measured with bitemesh's own functions (``quality_summary``, ``check_valid_domain``; volume error
against the exact volume).  Cells of gmsh/TetGen with negative signed volume are reoriented (and counted) and
unused nodes dropped before measuring, since ``check_valid_domain`` expects positive cells and no unused points.

Usage (from the repository root, in an environment with numpy, scipy and optionally gmsh, tetgen)::

    /work/bench-venv/bin/python benchmarks/peers.py --output benchmarks/peers.md
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SOURCE_ROOT = HERE.parent / "filters"
for p in (str(SOURCE_ROOT), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

from bitemesh.core import shapes  # noqa: E402
from bitemesh.core.mesh import Mesh  # noqa: E402
from bitemesh.core.quality import check_valid_domain, quality_summary  # noqa: E402
from golden import processor  # noqa: E402
from shape_worker import make_input  # noqa: E402

CALIBRATION_TOLERANCE = 0.05  # stop calibrating once the tet count is within 5 % of the target
CALIBRATION_ROUNDS = 3


# --- measuring -------------------------------------------------------------------------------------------------------

def measure(points, cells, shape) -> dict:
    """bitemesh's metrics of a tet mesh; negative cells are reoriented (counted) and unused nodes dropped."""
    points = np.asarray(points, float)
    cells = np.asarray(cells, np.int64).copy()
    used = np.unique(cells)
    remap = np.full(len(points), -1, np.int64)
    remap[used] = np.arange(used.size)
    unused = len(points) - used.size
    points, cells = points[used], remap[cells]
    a, b, c, d = (points[cells[:, i]] for i in range(4))
    signed = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)
    negative = signed < 0
    cells[negative] = cells[negative][:, [1, 0, 2, 3]]
    mesh = Mesh(points, cells)
    s = quality_summary(mesh)
    problems = check_valid_domain(mesh)
    return dict(cells=s.n_cells, points=s.n_points, q_mean=s.q_mean, q_min=s.q_min,
                angle_min=s.angle_min, percent_q_below_0_3=s.percent_q_below_0_3, edge_cv=s.edge_cv,
                volume_error_percent=100.0 * (s.total_volume - shape.measure) / shape.measure,
                valid=not problems, problems=problems[:3], reoriented=int(negative.sum()), unused_dropped=int(unused))


# --- bitemesh ----------------------------------------------------------------------------------------------------

def run_bitemesh(name: str, target: int, optimize: bool):
    from bitemesh.core.parameters import (BitingParameters, ImplicitParameters, OptimizeParameters,
                                          SpuriousParameters)
    from bitemesh.core.pipeline import run
    shape, points, normals, _ = make_input(name, target)
    start = time.perf_counter()
    result = run(points, normals, ImplicitParameters(), BitingParameters(cells=target), SpuriousParameters(),
                 optimize=OptimizeParameters(optimize=int(optimize)))
    seconds = time.perf_counter() - start
    return result.mesh.points, result.mesh.cells, seconds, f"{len(points)} noisy input points"


# --- gmsh --------------------------------------------------------------------------------------------------------

def gmsh_once(name: str, h: float):
    import gmsh
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(name)
        if name == "sphere":
            gmsh.model.occ.addSphere(0, 0, 0, 1.0)
        else:
            gmsh.model.occ.addTorus(0, 0, 0, 1.0, 0.4)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay (the default)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.option.setNumber("Mesh.OptimizeNetgen", 1)
        start = time.perf_counter()
        gmsh.model.mesh.generate(3)
        seconds = time.perf_counter() - start
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, node_tags = gmsh.model.mesh.getElementsByType(4)
    finally:
        gmsh.finalize()
    index = np.full(int(tags.max()) + 1, -1, np.int64)
    index[tags.astype(np.int64)] = np.arange(tags.size)
    return coords.reshape(-1, 3), index[node_tags.astype(np.int64).reshape(-1, 4)], seconds


def run_gmsh(name: str, target: int, shape):
    h = (shape.measure / target * 6 * np.sqrt(2) * 1.2) ** (1 / 3)  # regular-tet guess, slightly coarse
    for _ in range(CALIBRATION_ROUNDS):
        points, cells, seconds = gmsh_once(name, h)
        if abs(len(cells) / target - 1) < CALIBRATION_TOLERANCE:
            break
        h *= (len(cells) / target) ** (1 / 3)
    points, cells, seconds = gmsh_once(name, h)  # the timed run (warm, same size as the last calibration run)
    return points, cells, seconds, f"OCC exact {name}, h = {h:.4f}"


# --- TetGen ------------------------------------------------------------------------------------------------------

def icosphere(frequency: int):
    """Geodesic unit sphere: each icosahedron face split into frequency^2 triangles, projected on the sphere."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    n = frequency
    points, faces = [], []
    for a, b, c in f:
        ids = {}
        for i in range(n + 1):
            for j in range(n + 1 - i):
                ids[i, j] = len(points)
                points.append(v[a] + (v[b] - v[a]) * i / n + (v[c] - v[a]) * j / n)
        for i in range(n):
            for j in range(n - i):
                faces.append([ids[i, j], ids[i + 1, j], ids[i, j + 1]])
                if j < n - i - 1:
                    faces.append([ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]])
    points = np.array(points)
    points /= np.linalg.norm(points, axis=1)[:, None]
    keys = np.round(points, 9)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return points[first], inverse.reshape(-1)[np.array(faces)]


def torus_surface(nu: int, nv: int, major=1.0, minor=0.4):
    """Closed (u, v) grid triangulation of the torus, outward-oriented."""
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, V = np.meshgrid(u, v, indexing="ij")
    points = np.stack([(major + minor * np.cos(V)) * np.cos(U), (major + minor * np.cos(V)) * np.sin(U),
                       minor * np.sin(V)], axis=-1).reshape(-1, 3)
    idx = lambda i, j: (i % nu) * nv + (j % nv)  # noqa: E731
    faces = []
    for i in range(nu):
        for j in range(nv):
            faces.append([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)])
            faces.append([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)])
    return points, np.array(faces)


def tetgen_surface(name: str, h: float):
    if name == "sphere":
        return icosphere(max(2, round(1.05 / h)))  # icosahedron edge on the unit sphere ~1.05
    return torus_surface(max(8, round(2 * np.pi * 1.0 / h)), max(6, round(2 * np.pi * 0.4 / h)))


def tetgen_once(name: str, h: float, maxvolume: float):
    import tetgen
    surface_points, faces = tetgen_surface(name, h)
    tet = tetgen.TetGen(surface_points, faces.astype(np.int32))
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:  # the wrapper prints "parsing switches" on the C stdout
        os.dup2(null.fileno(), 1)
        try:
            start = time.perf_counter()
            nodes, elems, *_ = tet.tetrahedralize(switches=f"pq1.2a{maxvolume:.6g}Q")
            seconds = time.perf_counter() - start
        finally:
            os.dup2(saved, 1)
            os.close(saved)
    return nodes, elems[:, :4], seconds, len(surface_points)


def run_tetgen(name: str, target: int, shape):
    h = (shape.measure / target * 6 * np.sqrt(2)) ** (1 / 3)
    for _ in range(CALIBRATION_ROUNDS):
        maxvolume = h ** 3 / (6 * np.sqrt(2)) * 1.5
        points, cells, seconds, n_surface = tetgen_once(name, h, maxvolume)
        if abs(len(cells) / target - 1) < CALIBRATION_TOLERANCE:
            break
        h *= (len(cells) / target) ** (1 / 3)
    points, cells, seconds, n_surface = tetgen_once(name, h, maxvolume)
    return points, cells, seconds, f"-pq1.2a{maxvolume:.3g}, {n_surface} surface nodes (h = {h:.4f})"


# --- the run -------------------------------------------------------------------------------------------------------

def versions() -> dict:
    out = {"python": platform.python_version(), "numpy": np.__version__}
    import scipy
    out["scipy"] = scipy.__version__
    for module in ("gmsh", "tetgen"):
        try:
            out[module] = __import__(module).__version__
        except Exception as error:  # noqa: BLE001
            out[module] = f"not available ({type(error).__name__}: {error})"
    try:
        out["bitemesh"] = subprocess.run(["git", "-C", str(HERE.parent), "describe", "--always", "--dirty"],
                                         capture_output=True, text=True, check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        out["bitemesh"] = "?"
    return out


def machine() -> str:
    return (f"{platform.system()} {platform.release()} {platform.machine()}, {processor()}, "
            f"{os.cpu_count()} logical CPUs")


COLUMNS = [("mesher", "{}"), ("tets", "{:,}"), ("nodes", "{:,}"), ("mean Q", "{:.3f}"), ("min Q", "{:.3f}"),
           ("min dihedral (deg)", "{:.1f}"), ("% Q < 0.3", "{:.2f}"), ("edge CV", "{:.3f}"),
           ("volume error %", "{:+.2f}"), ("valid", "{}"), ("seconds (median)", "{:.2f}"),
           ("x bitemesh time", "{:.2f}")]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shapes", nargs="+", default=["sphere", "torus"], choices=["sphere", "torus"])
    parser.add_argument("--cells", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=3,
                        help="timed runs per mesher; seconds are the median, the metrics come from the first run")
    parser.add_argument("--output", type=Path)
    args = parser.parse_args(argv)

    meshers = [("bitemesh", lambda n, N, s: run_bitemesh(n, N, False)),
               ("bitemesh + optimize", lambda n, N, s: run_bitemesh(n, N, True)),
               ("gmsh Delaunay + Netgen opt.", run_gmsh),
               ("TetGen -pq1.2a", run_tetgen)]
    info = versions()
    lines = [f"# bitemesh beside gmsh and TetGen (~{args.cells:,} tets)", "",
             f"Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M UTC}  ",
             f"Machine: {machine()}  ",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in info.items()) + "  ",
             f"Command: `{Path(sys.executable).name} benchmarks/peers.py "
             + " ".join(argv if argv is not None else sys.argv[1:]) + "`", ""]
    notes = []
    for name in args.shapes:
        shape = getattr(shapes, name)()
        rows = []
        base_seconds = None
        for label, function in meshers:
            try:
                points, cells, seconds, note = function(name, args.cells, shape)
                times = [seconds] + [function(name, args.cells, shape)[2] for _ in range(args.repeat - 1)]
                seconds = float(np.median(times))
            except Exception as error:  # noqa: BLE001
                notes.append(f"- {name}, {label}: failed or not available: {type(error).__name__}: {error}")
                print(notes[-1], flush=True)
                continue
            m = measure(points, cells, shape)
            if base_seconds is None and label == "bitemesh":
                base_seconds = seconds
            ratio = seconds / base_seconds if base_seconds else float("nan")
            rows.append([label, m["cells"], m["points"], m["q_mean"], m["q_min"], m["angle_min"],
                         m["percent_q_below_0_3"], m["edge_cv"], m["volume_error_percent"],
                         "yes" if m["valid"] else "NO", seconds, ratio])
            extra = []
            if m["reoriented"]:
                extra.append(f"{m['reoriented']} cells reoriented")
            if m["unused_dropped"]:
                extra.append(f"{m['unused_dropped']} unused nodes dropped")
            if m["problems"]:
                extra.append("problems: " + "; ".join(m["problems"]))
            notes.append(f"- {name}, {label}: {note}" + (" (" + ", ".join(extra) + ")" if extra else ""))
            print(f"{name:7s} {label:28s} tets {m['cells']:6d} Q {m['q_mean']:.3f} min dihedral "
                  f"{m['angle_min']:.1f} {seconds:.2f} s", flush=True)
        lines += [f"## {name} (exact volume {shape.measure:.5f})", "",
                  "| " + " | ".join(c for c, _ in COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        for row in rows:
            lines.append("| " + " | ".join(fmt.format(v) for (_, fmt), v in zip(COLUMNS, row)) + " |")
        lines.append("")
    lines += [f"Seconds: median of {args.repeat} runs in this one process, single thread for gmsh "
              "(General.NumThreads = 1); bitemesh: the whole pipeline.run from scattered points (implicit fit "
              "included); gmsh: generate(3) from the exact CAD shape (calibration runs untimed); TetGen: "
              "tetrahedralize of a given surface triangulation (building the surface untimed).", "",
              "Notes per mesh:", ""] + notes + [""]
    text = "\n".join(lines)
    print(text)
    if args.output:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
