"""bitemesh and what it needs beyond Slicer's own packages: where the package is, and scipy installed on
first use (never numpy, VTK or SimpleITK, which Slicer bundles)."""
from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import numpy as np


def bitemeshSourceRoot() -> Path | None:
    """The folder that holds the ``bitemesh`` package: beside BiteMesh.py (extension), or ``filters/`` (checkout)."""
    here = Path(__file__).resolve()
    candidates = [here.parents[1]]
    if len(here.parents) > 3:
        candidates.append(here.parents[3] / "filters")
    for candidate in candidates:
        if (candidate / "bitemesh" / "__init__.py").is_file():
            return candidate
    return None


def addBitemeshToPath() -> None:
    root = bitemeshSourceRoot()
    if root is not None and str(root) not in sys.path:
        sys.path.insert(0, str(root))


addBitemeshToPath()

#: what bitemesh needs beyond the Python packages Slicer bundles (numpy, VTK, SimpleITK): module -> pip requirement.
REQUIREMENTS = {"scipy": "scipy>=1.9", "numba": "numba>=0.56", "threadpoolctl": "threadpoolctl>=3.1"}
#: Slicer bundles these and breaks if pip replaces them: never installed, whatever a requirement says.
NEVER_INSTALL = ("vtk", "simpleitk", "itk", "numpy")


class MissingRequirementError(ImportError):
    """A Python package bitemesh needs is absent and was not installed."""


def missingRequirements() -> list:
    """The pip requirements (of :data:`REQUIREMENTS`) whose module cannot be imported, e.g. ``["scipy>=1.9"]``."""
    return [requirement for module, requirement in REQUIREMENTS.items() if importlib.util.find_spec(module) is None]


def installRequirements(pipInstall=None, confirm=None, compileKernels=None) -> list:
    """Install the missing requirements (scipy, numba, threadpoolctl) with Slicer's pip, on first use, then compile
    bitemesh's numba kernels into numba's cache, as ``pip install .`` does, so that the first mesh does not wait
    for them (about a minute, once, while the install's wait cursor is up).

    Parameters
    ----------
    pipInstall : callable taking a list of requirement strings; default ``slicer.util.pip_install``
    confirm : callable(missing) -> bool asking the user, or None to install without asking
    compileKernels : callable(); default ``bitemesh.meshing.compile_kernels``

    Returns
    -------
    The requirements that were installed (empty when nothing was missing).

    numpy is pinned to the version Slicer bundles so that pip cannot replace it; VTK and SimpleITK are never named.
    """
    missing = missingRequirements()
    if not missing:
        return []
    named = {requirement.split(">")[0].split("=")[0].split("<")[0].strip().lower() for requirement in missing}
    if named & set(NEVER_INSTALL):
        raise MissingRequirementError(f"refusing to pip-install {sorted(named & set(NEVER_INSTALL))} into Slicer")
    if confirm is not None and not confirm(missing):
        raise MissingRequirementError(f"BiteMesh needs {', '.join(missing)}; it was not installed")
    if pipInstall is None:
        import slicer   # only here: the rest of BiteMeshLib.requirements and .parameters runs without Slicer
        pipInstall = slicer.util.pip_install
    pipInstall(missing + [f"numpy=={np.__version__}"])
    importlib.invalidate_caches()
    still = missingRequirements()
    if still:
        raise MissingRequirementError(f"installing {', '.join(still)} failed; install it from the Python console "
                                      f"with slicer.util.pip_install({still!r})")
    if compileKernels is None:
        from bitemesh.meshing import compile_kernels as compileKernels
    compileKernels()
    return missing


def requireBitemesh():
    """Import bitemesh, saying how to fix a missing requirement instead of a bare ImportError."""
    missing = missingRequirements()
    if missing:
        raise MissingRequirementError(f"BiteMesh needs {', '.join(missing)}: open the BiteMesh module (it offers to "
                                      f"install it) or run slicer.util.pip_install({missing!r})")
    import bitemesh
    return bitemesh

