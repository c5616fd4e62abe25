"""The record-keeping and the common checks of pvbatch_script.py, which imports this module inside pvbatch
(ParaView's Python, its VTK 9.2): every check by name with ``ok`` and a detail, the facts the test compares again
in its own Python, the mesh comparisons, and the checks of the environment and of the generated properties.

pvbatch_script.py patches ``inspect`` for ParaView 5.11 before it imports this module (which imports paraview).
"""
from __future__ import annotations

import math
import sys
import time
import traceback
from pathlib import Path

import bitemesh
import numpy as np
from bitemesh import algorithms
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain
from bitemesh.core.mesh.topology import connected_components
from paraview import servermanager

SPHERE_VOLUME = 4.0 / 3.0 * math.pi

checks: dict = {}
facts: dict = {"seconds": {}}


def check(name: str, ok, detail="") -> bool:
    """Record one named check (never raise: the test reports every check)."""
    checks[name] = {"ok": bool(ok), "detail": str(detail)}
    print(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}", flush=True)
    return bool(ok)


def guarded(name: str):
    """Run a block of checks; an exception becomes a failed check named after the block."""
    def decorate(function):
        def run(*args, **kwargs):
            try:
                return function(*args, **kwargs)
            except Exception:  # noqa: BLE001 - reported as a failed check with its traceback
                check(name, False, traceback.format_exc())
                return None
        return run
    return decorate


def updated(proxy, port: int = 0):
    """The VTK output of a proxy (builtin session: the algorithm itself), updated.

    (Not named ``output``: a Programmable Filter runs its script in ``__main__`` and then deletes the names
    ``inputs``, ``output``, ``request`` and ``myarg`` there.)
    """
    proxy.UpdatePipeline()
    return proxy.GetClientSideObject().GetOutputDataObject(port)


def same_mesh(name: str, mesh, reference) -> bool:
    """Same number of points and cells, same coordinates and connectivity, bit for bit."""
    shapes = (mesh.points.shape, mesh.cells.shape), (reference.points.shape, reference.cells.shape)
    equal = shapes[0] == shapes[1] and np.array_equal(mesh.points, reference.points) and \
        np.array_equal(mesh.cells, reference.cells)
    detail = f"{len(mesh.points)} points, {len(mesh.cells)} cells vs {len(reference.points)}, {len(reference.cells)}"
    if shapes[0] == shapes[1] and not equal:
        detail += f"; largest coordinate difference {np.abs(mesh.points - reference.points).max():.3g}"
    return check(name, equal, detail)


def valid_sphere(name: str, mesh) -> None:
    """A valid domain: no problem found, one component, boundary Euler characteristic 2, volume within 3 %."""
    problems = check_valid_domain(mesh)
    check(f"{name}: valid domain", problems == [], problems or "no problem found")
    components = int(connected_components(mesh.cells).max()) + 1
    check(f"{name}: one component", components == 1, f"{components} components")
    euler = boundary_euler_characteristic(mesh)
    check(f"{name}: boundary euler 2", euler == 2, f"euler {euler}")
    volume = float(signed_measures(mesh.points, mesh.cells).sum())
    check(f"{name}: volume within 3 %", abs(volume / SPHERE_VOLUME - 1) < 0.03,
          f"{volume:.4f} vs {SPHERE_VOLUME:.4f} ({100 * (volume / SPHERE_VOLUME - 1):+.2f} %)")
    check(f"{name}: quality arrays", {"RadiusRatio", "MinDihedralAngle", "MaxDihedralAngle", "Volume"}
          <= set(mesh.cell_data), sorted(mesh.cell_data))


def timed(name: str, proxy, port: int = 0):
    clock = time.perf_counter()
    data = updated(proxy, port)
    facts["seconds"][name] = round(time.perf_counter() - clock, 3)
    return data


@guarded("environment")
def environment(plugin: Path) -> None:
    import scipy
    import vtkmodules
    from vtkmodules.vtkCommonCore import vtkVersion
    facts["versions"] = {"python": sys.version.split()[0], "numpy": np.__version__, "scipy": scipy.__version__,
                         "vtk": vtkVersion.GetVTKVersion(),
                         "paraview": servermanager.vtkSMProxyManager.GetParaViewSourceVersion()}
    # the pip wheel lives in a site-packages folder; ParaView's VTK in its own (Debian: dist-packages)
    check("ParaView's own VTK (no pip vtk wheel)", "site-packages" not in vtkmodules.__file__, vtkmodules.__file__)
    check("bitemesh from the clone", Path(bitemesh.__file__).resolve().parent == plugin.resolve().parent,
          bitemesh.__file__)


@guarded("properties follow the parameter dataclasses")
def properties(proxies: dict) -> None:
    """Every field of each filter's dataclasses is a property with its default, range, choices or free text, and
    help."""
    problems = []
    for class_name, proxy in proxies.items():
        for item in getattr(algorithms, class_name).parameter_fields:
            name = "".join(part.capitalize() for part in item.name.split("_"))
            prop = proxy.GetProperty(name)
            if prop is None:
                problems.append(f"{class_name}.{name} missing")
                continue
            meta = item.metadata
            default = prop.GetElement(0)  # a new proxy holds the defaults
            help_text = prop.GetDocumentation().GetDescription() if prop.GetDocumentation() else ""
            if meta["help"] not in " ".join(help_text.split()):
                problems.append(f"{class_name}.{name}: help {help_text!r}")
            if "text" in meta:  # a string property without a domain
                domains = prop.NewDomainIterator()
                domains.Begin()
                if not prop.IsA("vtkSMStringVectorProperty") or default != item.default or not domains.IsAtEnd():
                    problems.append(f"{class_name}.{name}: {prop.GetClassName()}, default {default!r}, a domain "
                                    f"{None if domains.IsAtEnd() else domains.GetKey()}")
                continue
            if "choices" in meta:
                domain = prop.GetDomain("list")
                strings = [domain.GetString(i) for i in range(domain.GetNumberOfStrings())] if domain else None
                if strings != list(meta["choices"]) or default != item.default:
                    problems.append(f"{class_name}.{name}: choices {strings}, default {default}")
                continue
            low, high, low_open, _ = meta["range"]
            domain = prop.GetDomain("range")
            minimum = domain.GetMinimum(0) if domain and domain.GetMinimumExists(0) else None
            maximum = domain.GetMaximum(0) if domain and domain.GetMaximumExists(0) else None
            if item.default is None:  # optional: the automatic value -1 and the words
                automatic = -1
                if default != automatic or minimum != automatic or f"{automatic} means automatic" not in help_text:
                    problems.append(f"{class_name}.{name}: automatic {default}, min {minimum}")
            elif default != item.default or minimum != low:
                problems.append(f"{class_name}.{name}: default {default} vs {item.default}, min {minimum} vs {low}")
            expected_max = None if high is None or not math.isfinite(high) else min(high, 2**31 - 1)
            if maximum != expected_max:
                problems.append(f"{class_name}.{name}: max {maximum} vs {expected_max}")
            if meta["unit"] and f"[{meta['unit']}]" not in help_text:
                problems.append(f"{class_name}.{name}: no unit in help")
    check("properties follow the parameter dataclasses", not problems, problems or "every field checked")
