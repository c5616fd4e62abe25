"""Fixtures of the command-line tests: the input files, a reference mesh, a spy on the pipeline (the sphere's samples
of the awkward inputs: ``unit_sphere_samples`` in tests/conftest.py).

The data fixtures are built once for the folder (package scope): the tests only read them.
"""
from __future__ import annotations

import pytest
from bitemesh import meshing
from bitemesh.core.sources import points as pipeline
from bitemesh.core.shapes import annulus, sample_surface

from tests import builders
from tests.cli.commands import run_quietly, save_table


@pytest.fixture(scope="package")
def inputs(tmp_path_factory):
    """Scattered points of the unit sphere in several files, and of an annulus (2D, with normals)."""
    folder = tmp_path_factory.mktemp("inputs")
    points, normals = builders.sphere_samples(0.08, seed=1)
    files = {
        "xyz+normals": save_table(folder / "sphere_n.xyz", points, normals),
        "xyz": save_table(folder / "sphere.xyz", points),
        "csv+header": save_table(folder / "sphere.csv", points, normals, delimiter=",", header="x,y,z,nx,ny,nz"),
        "txt": save_table(folder / "sphere.txt", points),
    }
    ring, ring_normals = sample_surface(annulus(), 0.05, seed=1)
    files["annulus"] = save_table(folder / "annulus.xyz", ring, ring_normals)
    return files


@pytest.fixture(scope="package")
def reference(inputs, tmp_path_factory):
    """The sphere meshed once by ``bitemesh mesh --cells 2000`` (seed 0), as a .vtu."""
    path = tmp_path_factory.mktemp("reference") / "sphere.vtu"
    assert run_quietly(["mesh", str(inputs["xyz+normals"]), "-o", str(path), "--cells", "2000"]) == 0
    return path


@pytest.fixture
def pipeline_spy(monkeypatch):
    """Records whether ``bitemesh mesh`` reached the points' pipeline (through the front door)."""
    calls = []

    def spy(*args, **kwargs):
        calls.append(args)
        return pipeline.run(*args, **kwargs)
    monkeypatch.setattr(meshing, "run", spy)
    return calls
