"""The same meshes bit for bit: the quick cases of ``benchmarks/golden.py`` against their recorded fingerprints.

A refactoring must not change a mesh.  A change that is meant to change meshes re-records them
(``python benchmarks/golden.py --record``) and says why in its commit.  The fingerprints hold for the floating point
they were made with, so golden.json keeps one record per environment (numpy, scipy, processor); in one
without a record the test is skipped, saying so.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import golden  # noqa: E402

RECORDED = golden.recorded_here(json.loads(golden.RECORD.read_text()))
QUICK = [name for name, (_, quick) in golden.CASES.items() if quick]


@pytest.mark.slow
@pytest.mark.parametrize("name", QUICK)
def test_same_mesh_as_recorded(name):
    if RECORDED is None:
        pytest.skip(f"no fingerprints recorded for {golden.environment()} (benchmarks/golden.py --record)")
    if name not in RECORDED["meshes"]:
        pytest.skip(f"{name} is not recorded for this environment (benchmarks/golden.py --record --cases ...)")
    mesh = golden.CASES[name][0]()
    assert golden.fingerprint(mesh) == RECORDED["meshes"][name], \
        f"{name}: the mesh changed; if that is meant, re-record with python benchmarks/golden.py --record"


def test_fingerprint_sees_one_node_move():
    """The fingerprint tells meshes apart that differ by one coordinate's last bit."""
    import numpy as np

    from bitemesh.core.mesh.simplicial import Mesh
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    cells = np.array([[0, 1, 2, 3]])
    moved = points.copy()
    moved[3, 2] = np.nextafter(1.0, 2.0)
    assert golden.fingerprint(Mesh(points, cells)) != golden.fingerprint(Mesh(moved, cells))
    assert golden.fingerprint(Mesh(points, cells)) == golden.fingerprint(Mesh(points.copy(), cells.copy()))
