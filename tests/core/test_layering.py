"""The layering of DESIGN.md: bitemesh.core imports neither VTK nor anything above it."""
from __future__ import annotations

import pkgutil
import subprocess
import sys
from pathlib import Path

import bitemesh.core

FILTERS = Path(__file__).resolve().parents[2] / "filters"


def test_every_core_module_imports_without_vtk():
    modules = [f"bitemesh.core.{m.name}" for m in pkgutil.iter_modules(bitemesh.core.__path__)]
    assert "bitemesh.core.pipeline" in modules
    code = ("import sys; sys.modules['vtkmodules'] = None; sys.modules['vtk'] = None\n"
            f"for name in {modules!r}: __import__(name)\n"
            "loaded = [m for m, module in sys.modules.items() if module is not None]\n"
            "assert not any(m.startswith(('vtk', 'bitemesh.io', 'bitemesh.cli')) for m in loaded), loaded")
    subprocess.run([sys.executable, "-c", code], check=True, env={"PYTHONPATH": str(FILTERS)})
