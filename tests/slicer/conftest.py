"""Fixtures of the Slicer tests (run in slicer-core's own virtual environment; see tests/slicer/scenes.py).

Nothing here imports slicer at load time: in the main environment the test modules skip themselves.
"""
from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def no_vtk_errors(capfd):
    """Fail a test in which VTK or MRML printed an error or a warning (they do not raise)."""
    yield
    captured = capfd.readouterr()
    printed = [line for line in (captured.out + captured.err).splitlines()
               if any(mark in line for mark in (" ERR| ", " WARN| ", "ERROR:", "Warning:"))]
    assert not printed, "VTK printed:\n" + "\n".join(printed)


@pytest.fixture
def scene():
    from tests.slicer.scenes import slicer
    return slicer.vtkMRMLScene()


@pytest.fixture
def logic():
    from tests.slicer.scenes import BiteMeshLogic
    return BiteMeshLogic()
