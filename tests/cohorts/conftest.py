"""Fixtures of the cohort tests: small input files of every kind, a manifest naming them, and one 2-worker
LocalCluster shared by the folder (its Client)."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from bitemesh.core.shapes import annulus, sample_surface

from tests import builders
from tests.cli.commands import save_table
from tests.conftest import DATA

#: the cohort's own options: small meshes, the plain method (fast), as `bitemesh mesh --cells 1500 --no-optimize`
OPTIONS = {"cells": 1500, "optimize": 0}
FLAGS = ["--cells", "1500", "--no-optimize"]


def ball_file(path, size=40, spacing=0.5):
    """A voxelised ball (label 1) of ``size``^3 voxels written by SimpleITK."""
    import SimpleITK as sitk
    grid = np.ogrid[:size, :size, :size]
    ball = sum((axis - (size - 1) / 2) ** 2 for axis in grid) <= (0.38 * size) ** 2
    image = sitk.GetImageFromArray(ball.astype(np.uint8))
    image.SetSpacing((spacing,) * 3)
    image.SetOrigin((10.0, -5.0, 3.0))
    sitk.WriteImage(image, str(path), True)
    return path


@pytest.fixture(scope="package")
def inputs(tmp_path_factory):
    """name -> file: sphere points with normals, a 2D annulus, a label map, an unreadable table, and (where the real
    data is) the biv-me GPFile."""
    folder = tmp_path_factory.mktemp("cohort_inputs")
    points, normals = builders.sphere_samples(0.08, seed=1)
    ring, ring_normals = sample_surface(annulus(), 0.05, seed=1)
    files = {"sphere": save_table(folder / "sphere.xyz", points, normals),
             "annulus": save_table(folder / "annulus.xyz", ring, ring_normals),
             "ball": ball_file(folder / "ball.nrrd"),
             "broken": folder / "broken.xyz"}
    files["broken"].write_text("x y z\n1 2\n")
    gpfile = DATA / "bivme_patient1" / "GPFile_000.txt"
    if gpfile.is_file():
        files["heart"] = shutil.copy(gpfile, folder / "GPFile_000.txt")
    return files


@pytest.fixture(scope="package")
def client():
    """A Client of a LocalCluster of 2 worker processes, one thread each (the folder's tests share it)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") \
            as cluster, distributed.Client(cluster) as connected:
        yield connected


def write_manifest(path, rows, header=("input", "output")):
    """A manifest CSV: ``header`` and one line per row of cells."""
    path.write_text("\n".join(",".join(map(str, line)) for line in [header, *rows]) + "\n")
    return path
