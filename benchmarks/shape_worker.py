#!/usr/bin/env python
"""One case of ``run_benchmarks.py`` in a fresh process: a shape's scattered points meshed by bitemesh (the pipeline
worker) or, on the same grid I, by the paper's plain method (the baseline worker); its record written as JSON.

Run by run_benchmarks.py::

    python benchmarks/shape_worker.py {pipeline,baseline} SHAPE SIZE --json OUT.json --grid GRID.npz [--profile P]
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
import traceback
from pathlib import Path

SOURCE_ROOT = Path(__file__).resolve().parent.parent / "filters"
if str(SOURCE_ROOT) not in sys.path:
    sys.path.insert(0, str(SOURCE_ROOT))

from golden import fingerprint  # noqa: E402

#: command-line name -> factory name in bitemesh.core.shapes
SHAPES = {"sphere": "sphere", "die": "die", "torus": "torus", "two-cavity": "two_cavity_shell",
          "two-cavity-heart": "two_cavity_heart"}
#: point spacing of the input = this x the expected node spacing R
POINT_SPACING_PER_R = 0.5
#: noise standard deviation = this x the shape's size (largest side of its bounding box)
NOISE_PER_SIZE = 0.001
#: seed of the input sampling and of the biting
SEED = 0
#: a boundary vertex this deep (x R) is an interior node laid bare (a notch)
BOUNDARY_DISTANCE_LIMIT = 0.5


def _maxrss_mb(who=resource.RUSAGE_SELF) -> float:
    """Peak resident set size so far, MiB (Linux reports kilobytes)."""
    return resource.getrusage(who).ru_maxrss / 1024.0


def make_input(name: str, size: int):
    """The shape, its scattered noisy points and normals, and the sampling's parameters."""
    import numpy as np
    from bitemesh.core import shapes
    from bitemesh.core.steps.spine import radius_for_cells

    shape = getattr(shapes, SHAPES[name])()
    expected_r = radius_for_cells(shape.measure, size, shape.dim)
    extent = float(np.max(np.subtract(shape.upper, shape.lower)))
    spacing, noise = POINT_SPACING_PER_R * expected_r, NOISE_PER_SIZE * extent
    points, normals = shapes.sample_surface(shape, spacing, noise=noise, seed=SEED)
    return shape, points, normals, dict(expected_radius=expected_r, point_spacing=spacing, noise=noise,
                                        shape_size=extent, n_input_points=len(points))


def project_to_surface(shape, x, iterations: int = 60):
    """Feet of (m, 3) points on the analytic surface f = 0 by Newton steps along grad f (exact f, not the grid).

    The foot lies on the surface, so |x - foot| bounds the true distance from above.
    """
    import numpy as np
    foot = x.copy()
    for _ in range(iterations):
        value = shape.function(foot)
        gradient = shape.gradient(foot)
        foot = foot - (value / np.maximum(np.einsum("ij,ij->i", gradient, gradient), 1e-12))[:, None] * gradient
    return foot, np.abs(shape.function(foot))


def ellipsoid_distance_exact(x, centre, semi_axes, iterations: int = 200):
    """(m,) exact unsigned distance from (m, 3) points to an ellipsoid's surface (closest point by bisection).

    The closest point is q_i = a_i^2 y_i / (a_i^2 + t) with y = x - centre and t the root of
    sum_i (a_i y_i / (a_i^2 + t))^2 = 1 on (-min a_i^2, inf), where the left side decreases.
    """
    import numpy as np
    a2 = np.asarray(semi_axes, float) ** 2
    y = np.asarray(x, float) - np.asarray(centre, float)
    low = np.full(len(y), -a2.min() * (1 - 1e-15))
    high = np.full(len(y), np.sqrt(a2.max()) * np.linalg.norm(y, axis=1) + 1e-12)
    for _ in range(iterations):
        t = 0.5 * (low + high)
        above = np.sum(a2 * y**2 / (a2 + t[:, None]) ** 2, axis=1) > 1
        low, high = np.where(above, t, low), np.where(above, high, t)
    t = 0.5 * (low + high)
    return np.linalg.norm(y - a2 * y / (a2 + t[:, None]), axis=1)


def distance_lower_bound(name: str, x):
    """(m,) a lower bound of the true distance from points to the shape's surface, or None where not derived.

    The surface lies on the union of the full surfaces of the CSG pieces, so the smallest distance to those full
    surfaces bounds the true distance from below.  Sphere and torus: |f| is the exact distance.  Two-cavity shell:
    exact distances to the three full ellipsoids (parameters of ``shapes.two_cavity_shell``) and to the plane z = 0.
    """
    import numpy as np
    from bitemesh.core import shapes
    if name in ("sphere", "torus"):
        return np.abs(getattr(shapes, SHAPES[name])().function(x))
    if name == "two-cavity":
        pieces = [((0.0, 0.0, 0.0), (1.0, 0.9, 1.6)), ((0.3, 0.0, 0.0), (0.4, 0.4, 1.2)),
                  ((-0.55, 0.0, 0.0), (0.22, 0.55, 1.0))]
        return np.min([np.abs(x[:, 2])] + [ellipsoid_distance_exact(x, *piece) for piece in pieces], axis=0)
    return None


def mesh_metrics(mesh, shape, radius: float, name: str) -> dict:
    """Quality, geometry and validity figures of ``mesh`` against the analytic ``shape``."""
    import numpy as np
    from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain
    from bitemesh.core.mesh.topology import connected_components
    from bitemesh.core.mesh.quality import quality_summary
    from bitemesh.core.mesh.topology import boundary_facets

    summary = quality_summary(mesh)
    problems = check_valid_domain(mesh)
    labels = connected_components(mesh.cells)
    euler = boundary_euler_characteristic(mesh)
    on_boundary = np.unique(boundary_facets(mesh.cells))
    x = mesh.points[on_boundary]
    level = np.abs(shape.function(x))
    foot, residual = project_to_surface(shape, x)
    projected = np.linalg.norm(x - foot, axis=1)
    lower = distance_lower_bound(name, x)
    return dict(
        cells=summary.n_cells, points=summary.n_points, boundary_points=int(on_boundary.size),
        q_mean=summary.q_mean, q_std=summary.q_std, q_min=summary.q_min, q_p1=summary.q_p1,
        percent_q_below_0_1=summary.percent_q_below_0_1, percent_q_below_0_3=summary.percent_q_below_0_3,
        min_dihedral=summary.angle_min, max_dihedral=summary.angle_max,
        volume=summary.total_volume, measure=float(shape.measure),
        volume_error_percent=100.0 * (summary.total_volume - shape.measure) / shape.measure,
        boundary_f_max=float(level.max()), boundary_f_mean=float(level.mean()),
        boundary_projected_max=float(projected.max()), boundary_projected_mean=float(projected.mean()),
        notch_vertices=int(np.count_nonzero(projected > BOUNDARY_DISTANCE_LIMIT * radius)),
        projection_residual_max=float(residual.max()),
        f_minus_projected_max=float(np.max(level - projected)),
        projected_minus_f_max=float(np.max(projected - level)),
        lower_bound_max=None if lower is None else float(lower.max()),
        lower_bound_mean=None if lower is None else float(lower.mean()),
        bracket_width_max=None if lower is None else float(np.max(projected - lower)),
        edge_mean=summary.edge_mean, edge_cv=summary.edge_cv, radius=radius,
        problems=problems, valid=not problems, components=int(labels.max() + 1) if labels.size else 0,
        euler=int(euler), expected_euler=int(shape.boundary_euler), mesh_sha1=fingerprint(mesh),
    )


def worker_pipeline(name: str, size: int, grid_path: str | None) -> dict:
    """The whole bitemesh pipeline from scattered points with normals (default method mpu)."""
    import numpy as np
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters, SpuriousParameters
    from bitemesh.core.sources.points import run

    rss_imported = _maxrss_mb()
    clock = time.perf_counter()
    shape, points, normals, info = make_input(name, size)
    info["input_seconds"] = time.perf_counter() - clock
    rss_input = _maxrss_mb()
    clock, cpu = time.perf_counter(), time.process_time()
    result = run(points, normals, ImplicitParameters(), BitingParameters(cells=size, seed=SEED), SpuriousParameters())
    total, cpu = time.perf_counter() - clock, time.process_time() - cpu
    rss_run = _maxrss_mb()
    if grid_path:
        grid = result.implicit
        # the grid I is in the source's local frame (centred, unit size): R in its units, and the map back
        np.savez(grid_path, origin=grid.origin, spacing=grid.spacing, values=grid.values,
                 radius=result.radius / result.frame.scale, linear=result.frame.linear, shift=result.frame.shift)
    return dict(info, seconds=dict(result.seconds), total_seconds=total, cpu_seconds=cpu,
                grid_shape=list(result.implicit.shape),
                grid_spacing=float(np.max(result.implicit.spacing)), n_nodes=int(len(result.nodes)),
                rss_after_import_mb=rss_imported, rss_after_input_mb=rss_input, rss_after_run_mb=rss_run,
                metrics=mesh_metrics(result.mesh, shape, result.radius, name))


#: the baselines: name -> description (the outside test; none of them repairs the domain)
BASELINES = {"paper": "circumcentre test only (the paper)",
             "outside_cells": "bitemesh.core.steps.spurious.outside_cells, no repair"}


def worker_baseline(name: str, size: int, grid_path: str) -> dict:
    """The plain method on the pipeline's grid I: biting, Delaunay, an outside-cell test; no validity repair.

    Two outside tests on the same nodes and cells: the paper's circumcentre test alone, and bitemesh's current
    ``outside_cells`` (the circumcentre test with its refinements), to separate what the test changes from what the
    repair (``carve_domain``) changes.
    """
    import numpy as np
    from bitemesh.core import shapes
    from bitemesh.core.steps.biting import bite
    from bitemesh.core.steps.delaunay import delaunay
    from bitemesh.core.grid.sampled import ImplicitGrid
    from bitemesh.core.mesh.simplicial import Mesh
    from bitemesh.core.parameters import BitingParameters, SpuriousParameters
    from bitemesh.core.mesh.quality import cell_quality
    from bitemesh.core.sources.source import Frame
    from bitemesh.core.steps.spurious import circumcentre_outside, outside_cells

    rss_imported = _maxrss_mb()
    shape = getattr(shapes, SHAPES[name])()
    with np.load(grid_path) as saved:
        origin, spacing, values, radius = saved["origin"], saved["spacing"], saved["values"], float(saved["radius"])
        frame = Frame(saved["linear"], saved["shift"])
    grid = ImplicitGrid(origin=origin, spacing=spacing, values=values)
    defaults, threshold = BitingParameters(), SpuriousParameters().threshold
    shared = {}
    clock = time.perf_counter()
    nodes = bite(grid, radius, order=defaults.order, seed=SEED)
    shared["biting"] = time.perf_counter() - clock
    clock = time.perf_counter()
    cells = delaunay(nodes)
    shared["delaunay"] = time.perf_counter() - clock
    variants = {}
    def paper(grid, nodes, cells, threshold):   # the paper's circumcentre test alone
        return circumcentre_outside(grid, nodes, cells, threshold)[0]

    for variant, test in (("paper", paper), ("outside_cells", outside_cells)):
        # a fresh grid per variant: the cached gradient grids are computed (and timed) by each test
        fresh = ImplicitGrid(origin=origin, spacing=spacing, values=values)
        seconds = dict(shared)
        clock = time.perf_counter()
        kept = cells[~test(fresh, nodes, cells, threshold)]
        used = np.unique(kept)  # drop the nodes no kept cell uses (the plain method has no other clean-up)
        renumber = np.full(len(nodes), -1, dtype=np.int64)
        renumber[used] = np.arange(used.size)
        mesh = Mesh(nodes[used], renumber[kept])
        seconds["spurious cells"] = time.perf_counter() - clock
        clock = time.perf_counter()
        mesh = frame.mesh_to_user(mesh.with_cell_data(**cell_quality(mesh)))
        seconds["quality"] = time.perf_counter() - clock
        variants[variant] = dict(seconds=seconds, mesh_seconds=sum(seconds.values()),
                                 metrics=mesh_metrics(mesh, shape, radius * frame.scale, name))
    return dict(variants=variants, rss_after_import_mb=rss_imported, rss_after_run_mb=_maxrss_mb())


def main(argv=None) -> int:
    """Run one case, write its JSON; exceptions are reported in the JSON, not raised."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("worker", choices=("pipeline", "baseline"))
    parser.add_argument("shape", choices=list(SHAPES))
    parser.add_argument("size", type=int)
    parser.add_argument("--json", required=True, help="the record to write")
    parser.add_argument("--grid", help="the pipeline's grid I: written by the pipeline worker, read by the baseline")
    parser.add_argument("--profile", help="run under cProfile, write its stats to PROFILE.*")
    args = parser.parse_args(argv)
    if args.profile:
        import cProfile
        profiler = cProfile.Profile()
        profiler.enable()
    try:
        if args.worker == "pipeline":
            record = worker_pipeline(args.shape, args.size, args.grid)
        else:
            record = worker_baseline(args.shape, args.size, args.grid)
        record["ok"] = True
    except Exception as error:  # noqa: BLE001 - a benchmark records failures and goes on
        record = dict(ok=False, error=f"{type(error).__name__}: {error}", traceback=traceback.format_exc())
    if args.profile:
        import io
        import pstats
        profiler.disable()
        for sort in ("cumulative", "tottime"):
            text = io.StringIO()
            pstats.Stats(profiler, stream=text).sort_stats(sort).print_stats(30)
            Path(f"{args.profile}.{sort}.txt").write_text(text.getvalue())
        profiler.dump_stats(f"{args.profile}.prof")
    Path(args.json).write_text(json.dumps(record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
