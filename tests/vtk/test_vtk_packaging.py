"""The VTK side's packaging: the test folder captures VTK's errors, ``import bitemesh`` alone loads no VTK, the
algorithms import only ``vtkmodules`` (never paraview or slicer) and call only VTK 9.2's API (ParaView 5.11).

Every test here also fails if VTK printed an error or a warning (tests/vtk/conftest.py), unless it asks for the
``vtk_errors`` fixture.
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow


ROOT = Path(__file__).resolve().parents[2]
ALGORITHMS = ROOT / "filters" / "bitemesh" / "algorithms"


# ------------------------------------------------------------------------------------------------ packaging


def test_the_fixture_captures_vtk_errors(vtk_errors):
    """The conftest's window is in place: what VTK prints is captured (and this test expects it)."""
    assert isinstance(vtkOutputWindow.GetInstance(), vtkStringOutputWindow)
    vtkOutputWindow.GetInstance().DisplayErrorText("ERROR: a test error\n")
    assert vtk_errors.messages() == ["ERROR: a test error"]


def test_import_bitemesh_alone_does_not_load_vtk():
    code = ("import sys, bitemesh\n"
            "assert not [m for m in sys.modules if m.startswith('vtk')], sorted(sys.modules)\n"
            "from bitemesh import PointsToImplicit, MeshFromPoints\n"
            "from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase\n"
            "assert issubclass(PointsToImplicit, VTKPythonAlgorithmBase)\n"
            "assert 'vtk' not in sys.modules\n"
            "print('ok')\n")
    env = {"PYTHONPATH": str(ROOT / "filters"), "PATH": "/usr/bin:/bin"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


def test_the_algorithms_import_only_vtkmodules():
    sources = {path.name: path.read_text() for path in [*ALGORITHMS.glob("*.py"), ALGORITHMS.parent / "convert.py"]}
    assert len(sources) >= 4
    for name, text in sources.items():
        assert not re.search(r"^\s*(import\s+vtk\b|from\s+vtk\b)", text, re.MULTILINE), name
        assert "paraview" not in text and "slicer" not in text.lower(), name


#: The VTK API the algorithms call, each checked present in VTK 9.2 (ParaView 5.11's VTK).  A method missing here
#: fails the test below: check it in the VTK 9.2 documentation before adding it.
VTK_9_2_API = {
    # vtkAlgorithm / VTKPythonAlgorithmBase (VTK 5 and later; vtkmodules.util.vtkAlgorithm since 8.1)
    "Update", "Modified", "GetMTime", "UpdateProgress", "SetProgressText", "GetAbortExecute", "HasObserver",
    "InvokeEvent", "GetNumberOfInputPorts", "GetNumberOfOutputPorts", "GetNumberOfInputConnections",
    "GetInputAlgorithm", "GetInputConnection", "GetIndex", "GetOutputDataObject", "SetInputDataObject",
    # information objects and keys
    "Get", "Set", "Has", "GetInformationObject", "GetNumberOfInformationObjects", "GetData", "ORIGIN", "SPACING",
    "DATA_OBJECT", "DATA_TYPE_NAME", "WHOLE_EXTENT", "UPDATE_EXTENT", "INPUT_REQUIRED_DATA_TYPE",
    # data objects
    "GetPoints", "SetPoints", "GetNumberOfPoints", "GetNumberOfCells", "GetPointData", "GetCellData",
    "GetFieldData", "GetArray", "AddArray", "GetNumberOfArrays", "GetName", "SetName", "GetNormals", "GetScalars",
    "SetScalars", "SetVerts", "ShallowCopy", "Initialize", "SetExtent", "SetOrigin", "SetSpacing", "GetOrigin",
    "GetSpacing", "GetDimensions", "SetCells", "GetCells", "GetCellType", "GetCellTypesArray", "AddColumn",
    "InsertNextValue", "SetData", "GetOffsetsArray", "GetConnectivityArray",  # vtkCellArray: VTK 9.0
    "GetInstance", "DisplayErrorText", "DisplayWarningText", "GetVTKMajorVersion", "GetVTKMinorVersion",
    "GetCellTypes",  # called only where vtkVersion says 9.6 or later
    "DisplayText", "PassData",  # vtkOutputWindow (VTK 4), vtkFieldData (VTK 5)
    # string point arrays (Label): run in ParaView 5.11's pvpython (VTK 9.2.20230111)
    "GetAbstractArray", "GetNumberOfComponents", "GetNumberOfTuples", "IsA", "GetValue",
    "SetActiveVectors",  # vtkDataSetAttributes (FibreField's Fibre for glyphs): in ParaView 5.11's pvpython
    "SetActiveScalars",  # vtkDataSetAttributes (VentricularCoordinates' AHA): in ParaView 5.11's pvpython
}


def test_the_algorithms_use_only_vtk_9_2_api():
    called = set()
    for path in ALGORITHMS.glob("*.py"):
        called |= set(re.findall(r"\.([A-Z][A-Za-z0-9_]*)\(", path.read_text()))
    assert called - VTK_9_2_API == set(), "check these in VTK 9.2, then list them in VTK_9_2_API"
