"""How far the zero set of method='rbf' lies from the true surface, on sparse 2D and 3D samples.

Each case fits ``fit_implicit(points, normals, method="rbf")`` to samples of an analytic shape (exact normals),
finds the zero set on a grid (every grid edge whose ends differ in sign, the crossing refined by bisection on f
itself, so the grid adds no error), and reports the distance of those points to the true surface (|signed
distance of the shape|: mean, RMS, max, in units of the shape's size 1), the largest distance from the true surface
to the zero set (a part of the surface the zero set misses), and the fit and evaluation times.  The max is the
clamp by the samples' bounding box wherever the samples do not reach the shape's extreme (a sphere's poles: the
zero set is cut flat there), so the mean and the RMS compare the fits.

    python benchmarks/rbf_accuracy.py               # every case
    python benchmarks/rbf_accuracy.py --cases "annulus 120" "sphere 300"
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

SOURCE_ROOT = Path(__file__).resolve().parents[1] / "filters"
if str(SOURCE_ROOT) not in sys.path:
    sys.path.insert(0, str(SOURCE_ROOT))

from bitemesh.core.implicit.fit import fit_implicit  # noqa: E402
from bitemesh.core.shapes import annulus, sample_surface, sphere  # noqa: E402


def annulus_contours():
    """The annulus of tests/core/implicit/test_implicit.py: 80 points on r = 1, 40 on r = 0.5, outward normals."""
    angle = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    circle = np.c_[np.cos(angle), np.sin(angle)]
    shape = annulus(1.0, 0.5)
    return shape, np.vstack([circle, 0.5 * circle[::2]]), np.vstack([circle, -circle[::2]])


def annulus_sampled(spacing: float):
    """shapes.annulus (r = 1 and 0.4) sampled about ``spacing`` apart (tests/core/sources/test_points.py: 0.02)."""
    shape = annulus()
    points, normals = sample_surface(shape, spacing, seed=2)
    return shape, points, normals


def sphere_random(count: int, seed: int = 0):
    """``count`` points uniform on the unit sphere, exact normals."""
    normals = np.random.default_rng(seed).normal(size=(count, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return sphere(), normals.copy(), normals


def sphere_slices(slices: int = 7, per_slice: int = 40):
    """Contours of the unit sphere on ``slices`` parallel planes (closed curves traced on short-axis slices), with
    their exact (3D) normals."""
    rows = []
    for z in np.linspace(-0.85, 0.85, slices):
        angle = np.linspace(0, 2 * np.pi, per_slice, endpoint=False)
        r = np.sqrt(1 - z * z)
        rows.append(np.c_[r * np.cos(angle), r * np.sin(angle), np.full(per_slice, z)])
    points = np.vstack(rows)
    return sphere(), points, points.copy()


CASES = {
    "annulus 120": annulus_contours,
    "annulus 0.02": lambda: annulus_sampled(0.02),
    "annulus 0.005": lambda: annulus_sampled(0.005),
    "sphere 300": lambda: sphere_random(300),
    "sphere 1500": lambda: sphere_random(1500),
    "sphere 5000": lambda: sphere_random(5000),
    "sphere 7 slices": lambda: sphere_slices(),
}


def zero_set(function, lower, upper, step: float) -> np.ndarray:
    """(m, k) points of f = 0 on the grid edges of spacing ``step`` over [lower, upper], refined by bisection."""
    axes = [np.arange(a, b + step / 2, step) for a, b in zip(lower, upper)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    values = np.concatenate([function(part) for part in np.array_split(nodes.reshape(-1, len(axes)),
                                                                        max(1, nodes.size // 300000))])
    values = values.reshape(nodes.shape[:-1])
    found = []
    for axis in range(len(axes)):
        first = [slice(None)] * len(axes)
        second = [slice(None)] * len(axes)
        first[axis], second[axis] = slice(None, -1), slice(1, None)
        a, b = values[tuple(first)], values[tuple(second)]
        cross = (a > 0) != (b > 0)
        low, high = nodes[tuple(first)][cross], nodes[tuple(second)][cross]
        f_low = a[cross]
        for _ in range(30):
            middle = (low + high) / 2
            f_middle = function(middle)
            same = (f_middle > 0) == (f_low > 0)
            low = np.where(same[:, None], middle, low)
            f_low = np.where(same, f_middle, f_low)
            high = np.where(same[:, None], high, middle)
        found.append((low + high) / 2)
    return np.vstack(found)


def measure(name: str, step: float, kernel=None) -> dict:
    shape, points, normals = CASES[name]()
    start = time.perf_counter()
    if kernel is None:
        function = fit_implicit(points, normals, method="rbf")
    else:   # the same fit with another kernel
        from bitemesh.core.implicit.rbf import fit_rbf
        function = fit_rbf(points, normals, kernel=kernel)
    fitted = time.perf_counter()
    lower, upper = np.array(shape.lower) - 0.3, np.array(shape.upper) + 0.3
    zeros = zero_set(function, lower, upper, step)
    evaluated = time.perf_counter()
    distance = np.abs(shape.function(zeros))
    truth, _ = sample_surface(shape, step, seed=5)
    missed = cKDTree(zeros).query(truth)[0].max() if len(zeros) else np.inf
    return dict(points=len(points), mean=distance.mean(), rms=np.sqrt(np.mean(distance ** 2)), max=distance.max(),
                missed=missed, fit=fitted - start, evaluate=evaluated - fitted)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--kernel", default=None, help="fit_rbf's kernel instead of method 'rbf''s default")
    parser.add_argument("--step", type=float, default=None, help="grid spacing (default 0.01 in 2D, 0.03 in 3D)")
    args = parser.parse_args(argv)
    print(f"{'case':16s} {'points':>6s} {'mean':>9s} {'rms':>9s} {'max':>9s} {'missed':>9s} {'fit s':>7s} "
          f"{'eval s':>7s}")
    for name in args.cases:
        step = args.step or (0.01 if name.startswith("annulus") else 0.03)
        try:
            found = measure(name, step, args.kernel)
        except Exception as error:   # noqa: BLE001 (a refusal is a result)
            print(f"{name:16s} {type(error).__name__}: {error}")
            continue
        print(f"{name:16s} {found['points']:6d} {found['mean']:9.2e} {found['rms']:9.2e} {found['max']:9.2e} "
              f"{found['missed']:9.2e} {found['fit']:7.2f} {found['evaluate']:7.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
