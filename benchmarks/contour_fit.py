#!/usr/bin/env python
"""The contour fit's cost against the density of the contours (issue 10: 10,000 guide points in <= 5 s).

For the shipped biv-me case and its contours resampled 4x and 6x denser (tests/cardiac_variants.py), the median of
``--repeats`` runs of ``labelled_implicit`` (thinning, normals, the partition-of-unity RBF fit and the sampling of
each surface on its grid), then of the sampling of the domain on the grid I at R = 2 mm (the spine's first step,
whose cost follows R, not the density).

Usage (from the repository root)::

    python benchmarks/contour_fit.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from bitemesh.core.sources.contours.fit import labelled_implicit  # noqa: E402
from bitemesh.core.sources.contours.run import labelled_source  # noqa: E402
from bitemesh.core.parameters import BitingParameters, ImplicitParameters  # noqa: E402
from bitemesh.core.steps.spine import grid_for_source  # noqa: E402
from bitemesh.io import read_labelled_points  # noqa: E402

from tests.cardiac_variants import variant_file  # noqa: E402

SHIPPED = HERE.parent.parent / "shared" / "data" / "bivme_patient1" / "GPFile_000.txt"


def median_seconds(repeats: int, run, *args, **options) -> float:
    """The median wall-clock seconds of ``run(*args, **options)`` over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        clock = time.perf_counter()
        run(*args, **options)
        times.append(time.perf_counter() - clock)
    return float(np.median(times))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    print("| contours | guide points | labelled_implicit (s) | grid I at R = 2 mm (s) |\n|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name in ("shipped", "denser 4x", "denser 6x"):
            points, labels, slices = read_labelled_points(variant_file(SHIPPED, name, folder))
            fit = median_seconds(args.repeats, labelled_implicit, points, labels, slices=slices)
            source = labelled_source(points, labels, slices=slices)
            sampling = median_seconds(args.repeats, grid_for_source, source, ImplicitParameters(),
                                      BitingParameters(radius=2.0))
            print(f"| {name} | {len(points):,} | {fit:.2f} | {sampling:.2f} |", flush=True)


if __name__ == "__main__":
    main()
