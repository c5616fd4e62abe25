"""Fingerprints of the meshes bitemesh makes, to hold a refactoring to "the same meshes bit for bit".

Each case is meshed in this process and fingerprinted by the SHA-1 of its node coordinates and cells (float64 and
int64 bytes).  ``--record`` writes them to ``golden.json`` beside this file, with the versions of Python, numpy,
scipy and numba and the processor's instruction sets they were made with (floating point may differ elsewhere);
without it the cases are meshed and compared, and the exit status is 1 when one differs.  ``tests/test_golden.py``
compares the quick cases.

    python benchmarks/golden.py                  # compare every case
    python benchmarks/golden.py --record         # after a change that is meant to change meshes: say why in the commit
"""
from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import scipy

RECORD = Path(__file__).with_name("golden.json")


def fingerprint(mesh) -> str:
    """SHA-1 (hex, 16 digits) of a mesh's float64 coordinates and int64 cells."""
    digest = hashlib.sha1(np.ascontiguousarray(mesh.points, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(mesh.cells, dtype=np.int64).tobytes())
    return digest.hexdigest()[:16]


def die_demo(cells: int = 10000, optimize: int = 1):
    """``bitemesh demo`` (die): its points, its parameters (optimize 1, the default; 0: the plain method)."""
    from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters
    from bitemesh.core.sources.points import run
    from bitemesh.core.shapes import die_samples
    points, normals = die_samples()
    return run(points, normals, ImplicitParameters(), BitingParameters(cells=cells),
               optimize=OptimizeParameters(optimize=optimize)).mesh


def heart_demo(cells: int | None = 40000, optimize: int = 1):
    """``bitemesh demo heart --cells N``'s mesh (the shipped biv-me guide points); None: the cardiac default
    (R = 2 mm), as ``bitemesh mesh GPFile_000.txt`` meshes it; ``optimize`` 0: the plain method."""
    from bitemesh.core.sources.contours.run import run_labelled
    from bitemesh.core.parameters import BitingParameters, OptimizeParameters
    from bitemesh.io import read_labelled_points
    source = resources.files("bitemesh") / "data" / "bivme_patient1" / "GPFile_000.txt"
    with resources.as_file(source) as path:
        points, labels, slices = read_labelled_points(path)
    biting = BitingParameters() if cells is None else BitingParameters(cells=cells)
    return run_labelled(points, labels, slices=slices, biting=biting,
                        optimize=OptimizeParameters(optimize=optimize)).mesh


def benchmark_shape(name: str, cells: int, optimize: int = 1):
    """A shape of ``benchmarks/run_benchmarks.py`` from its noisy scattered points, default parameters
    (``optimize`` 0: the plain method)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from shape_worker import SEED, make_input

    from bitemesh.core.parameters import BitingParameters, OptimizeParameters
    from bitemesh.core.sources.points import run
    _, points, normals, _ = make_input(name, cells)
    return run(points, normals, biting=BitingParameters(cells=cells, seed=SEED),
               optimize=OptimizeParameters(optimize=optimize)).mesh


def label_map_ball(cells: int = 10000, optimize: int = 1):
    """Two labels of a voxel ball (an inner ball and its shell), anisotropic voxels, a rotated direction, meshed as
    two regions (their union's mesh, the interface sampled and snapped) by :func:`bitemesh.labelmap.mesh_label_grid`."""
    from bitemesh.core.parameters import BitingParameters, OptimizeParameters
    from bitemesh.labelmap import mesh_label_grid
    index = np.indices((48, 40, 56)).transpose(1, 2, 3, 0) - np.array([24, 20, 28])
    spacing = np.array([1.0, 1.2, 0.85])
    radius = np.linalg.norm(index * spacing, axis=-1)
    labels = np.where(radius < 12, 1, np.where(radius < 19, 2, 0))
    angle = 0.3
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation * spacing, [-80.0, 120.0, 35.0]
    return mesh_label_grid(labels, matrix, labels={1, 2}, biting=BitingParameters(cells=cells),
                           optimize=OptimizeParameters(optimize=optimize)).mesh


#: name -> (how to mesh it, quick enough for the test suite)
#: the default (optimize 1) on the shapes, the plain method (optimize 0) where the optimizer would make the suite
#: slow (the heart at 40k, the label map) and on a die, so that both paths are held
CASES = {
    "die 10k": (lambda: die_demo(), True),
    "die 10k plain": (lambda: die_demo(optimize=0), True),
    "heart 40k plain": (lambda: heart_demo(optimize=0), True),
    "sphere 10k": (lambda: benchmark_shape("sphere", 10000), True),
    "torus 10k": (lambda: benchmark_shape("torus", 10000), True),
    "two-cavity 10k": (lambda: benchmark_shape("two-cavity", 10000), True),
    "label map 10k plain": (lambda: label_map_ball(optimize=0), True),
    "die 136k": (lambda: benchmark_shape("die", 136000), False),
    "heart 40k": (lambda: heart_demo(), False),
    "heart R 2 mm": (lambda: heart_demo(None), False),
}


def processor() -> str:
    """The processor's model name (numpy and OpenBLAS pick their SIMD kernels by it: an AMD EPYC and an Intel Xeon
    round the same pipeline differently)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def instruction_sets() -> str:
    """The SIMD instructions floating point is rounded with here: numpy's dispatch targets this processor runs
    (X86_V3: AVX2 and FMA, X86_V4: AVX-512, ...) and the processor numba compiles for (LLVM's name).  Two AMD EPYC
    machines with and without AVX-512 make different golden meshes from the same code."""
    import llvmlite.binding
    from numba.core import config
    from numpy._core import _multiarray_umath as umath
    found = [name for name in umath.__cpu_dispatch__ if umath.__cpu_features__.get(name)]
    return f"numpy {' '.join(found) or 'baseline'}, numba {config.CPU_NAME or llvmlite.binding.get_host_cpu_name()}"


def environment() -> dict:
    """What floating point results depend on here."""
    import numba
    return dict(python=platform.python_version(), numpy=np.__version__, scipy=scipy.__version__,
                numba=numba.__version__, machine=platform.machine(), system=platform.system(),
                processor=processor(), instructions=instruction_sets())


def recorded_here(records: list):
    """The record (environment, meshes) of golden.json made in this :func:`environment`, or None."""
    return next((record for record in records if record["environment"] == environment()), None)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", action="store_true", help="write golden.json instead of comparing")
    parser.add_argument("--quick", action="store_true", help="only the cases the test suite runs")
    parser.add_argument("--cases", nargs="+", choices=list(CASES), help="only these cases")
    parser.add_argument("--keep-others", action="store_true",
                        help="with --record: keep the other environments' records (for a refactoring that was "
                             "checked here, recorded where a record was missing); by default a record drops them, "
                             "since a change meant to change meshes makes them wrong")
    args = parser.parse_args(argv)
    names = [name for name, (_, quick) in CASES.items() if (quick or not args.quick)
             and (not args.cases or name in args.cases)]
    found = {}
    for name in names:
        found[name] = fingerprint(CASES[name][0]())
        print(f"{name:20s} {found[name]}", flush=True)
    records = json.loads(RECORD.read_text()) if RECORD.exists() else []
    mine = recorded_here(records)
    if args.record:
        kept = mine["meshes"] if mine is not None and (args.cases or args.quick) else {}
        meshes = {name: found.get(name, kept.get(name)) for name in CASES if name in found or name in kept}
        others = [record for record in records if record is not mine]
        if not args.keep_others and others:
            print(f"dropped the records of {len(others)} other environments (their meshes are the old ones)")
            others = []
        RECORD.write_text(json.dumps(others + [dict(environment=environment(), meshes=meshes)], indent=1) + "\n")
        print(f"recorded {len(found)} meshes for {environment()} in {RECORD}")
        return 0
    if mine is None:
        print(f"no fingerprints recorded for {environment()}: record them with --record")
        return 1
    differ = [name for name in names if mine["meshes"].get(name) != found[name]]
    print("all the same" if not differ else f"different: {', '.join(differ)}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
