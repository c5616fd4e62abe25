"""The VTK tests' fixtures: the sphere's samples and the filter chains on them, and VTK's output checked.

The VTK tests fail when VTK prints an error or a warning (as pyvista's test suite does).

A vtkStringOutputWindow replaces VTK's output window while the tests of this folder run (and the previous window
comes back afterwards), so that nothing VTK prints is lost; each test then fails if VTK printed "ERROR" or
"Warning" since the previous test ended, unless the test asks for the ``vtk_errors`` fixture, which says that
errors are expected and gives the test the text to check.
"""
from __future__ import annotations

import pytest
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow

from tests import builders

#: what VTK's error and warning macros (and bitemesh's filters) put in front of their messages.
ALARMS = ("ERROR", "Warning")


class VTKOutput:
    """VTK's text output since the last check (vtkStringOutputWindow cannot be emptied from Python)."""

    def __init__(self):
        self.window = vtkStringOutputWindow()
        self.checked = 0
        self.expected = False

    def text(self) -> str:
        """Everything VTK printed since the last check."""
        return self.window.GetOutput()[self.checked:]

    def messages(self) -> list:
        """The lines of ``text()`` that hold an error or a warning."""
        return [line for line in self.text().splitlines() if any(alarm in line for alarm in ALARMS)]

    def clear(self) -> None:
        """Forget what was printed so far (the next ``text()`` starts here)."""
        self.checked = len(self.window.GetOutput())


@pytest.fixture(scope="package", autouse=True)
def vtk_output():
    """A vtkStringOutputWindow as VTK's output window for the tests of this folder; the previous one after."""
    previous = vtkOutputWindow.GetInstance()
    output = VTKOutput()
    vtkOutputWindow.SetInstance(output.window)
    try:
        yield output
    finally:
        vtkOutputWindow.SetInstance(previous)


@pytest.fixture(autouse=True)
def fail_on_vtk_errors(vtk_output):
    """Fail the test if VTK printed an error or a warning while it (or a fixture it uses) ran."""
    vtk_output.expected = False
    yield
    messages, text = vtk_output.messages(), vtk_output.text()
    vtk_output.clear()
    if messages and not vtk_output.expected:
        pytest.fail(f"VTK printed {len(messages)} error or warning line(s):\n{text}", pytrace=False)


@pytest.fixture
def vtk_errors(vtk_output, fail_on_vtk_errors):
    """For a test that expects VTK errors: they do not fail it, and ``vtk_errors.text()`` is what VTK printed
    during the test (``vtk_errors.clear()`` starts afresh)."""
    pending = vtk_output.messages()
    assert not pending, f"VTK printed errors before the test began (in a fixture): {pending}"
    vtk_output.clear()
    vtk_output.expected = True
    return vtk_output


# --- the sphere and the filter chains on it ----------------------------------------------------------------------


@pytest.fixture(scope="package")
def sphere_samples():
    """Noisy scattered points on the unit sphere, with their exact outward normals."""
    return builders.sphere_samples(0.1, noise=0.002, seed=1)


@pytest.fixture(scope="package")
def sphere_chain(sphere_samples):
    """The pipeline on the sphere's points with normals, about 8000 cells, run once."""
    points, normals = sphere_samples
    pipeline = builders.chain(builders.polydata(points, normals), cells=8000)
    pipeline.quality.update()
    return pipeline


@pytest.fixture
def small_chain(sphere_samples):
    """A quick pipeline (coarse grid, about 1000 cells) on the sphere's points with normals, not yet run."""
    points, normals = sphere_samples
    return builders.chain(builders.polydata(points, normals), cells=1000, grid_spacing=0.06)
