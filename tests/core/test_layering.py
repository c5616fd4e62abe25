"""The layering of docs/layers.toml (drawn in docs/architecture.md): ``core`` <- ``convert`` <- ``io`` <- ``labelmap``
<- the front door (``options``, ``meshing``) <- {the VTK filters (``algorithms``), ``cohorts``} <- {``cli``,
``paraview_plugin``, the Slicer module}, and nothing points back; only the front door tells inputs apart.

The import graph is read from the source with ast: every ``import`` and ``from ... import`` of every module under
filters/bitemesh and slicer_module/BiteMesh, absolute and relative, at module level or inside a function (and
``importlib.import_module`` of a constant name).  ``from bitemesh import cli`` counts as importing bitemesh.cli.  A
failure names each importing module (file and line) and what it imports.  Another test imports every core module
with VTK made unimportable.
"""
from __future__ import annotations

import ast
import pkgutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import bitemesh
import bitemesh.core

ROOT = Path(__file__).resolve().parents[2]
FILTERS = ROOT / "filters"
SLICER_MODULE = ROOT / "slicer_module" / "BiteMesh"
#: the rooms of the package: its subpackages and top-level modules (core, convert, io, labelmap, algorithms, cli,
#: paraview_plugin)
ROOMS = frozenset(module.name for module in pkgutil.iter_modules(bitemesh.__path__))
VTK = ("vtk", "vtkmodules")


# --- reading the import graph -------------------------------------------------------------------------------------


def module_name(path: Path, root: Path) -> tuple[str, bool]:
    """The dotted name of the module at ``path`` (relative to the source root ``root``) and whether it is a
    package's __init__."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    package = parts[-1] == "__init__"
    return ".".join(parts[:-1] if package else parts), package


def resolve(name: str, package: bool, level: int, module: str | None) -> str:
    """The absolute name of ``from <level dots><module> import ...`` written in the module ``name``."""
    if level == 0:
        return module or ""
    base = name.split(".") if package else name.split(".")[:-1]
    base = base[:len(base) - (level - 1)] if level > 1 else base
    return ".".join(base + ([module] if module else []))


def imports_of(path: Path, root: Path) -> list[tuple[str, int]]:
    """(imported module, line) for every import in the file, wherever it stands in the file."""
    name, package = module_name(path, root)
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = resolve(name, package, node.level, node.module)
            found.append((base, node.lineno))
            # ``from bitemesh import cli`` imports the module bitemesh.cli (an attribute such as
            # ``from bitemesh.core.errors import InvalidInputError`` stays in its module's room)
            found += [(f"{base}.{alias.name}", node.lineno) for alias in node.names if alias.name != "*"]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str) \
                and getattr(node.func, "attr", getattr(node.func, "id", None)) in ("import_module", "__import__"):
            text = node.args[0].value
            level = len(text) - len(text.lstrip("."))
            found.append((resolve(name, package, level, text.lstrip(".") or None), node.lineno))
    return sorted(found, key=lambda item: item[1])


def import_graph(*roots: tuple[Path, Path]) -> dict:
    """module name -> (file, [(imported module, line)]) for every .py file under each (folder, source root)."""
    graph = {}
    for folder, root in roots:
        for path in sorted(folder.rglob("*.py")):
            if "__pycache__" not in path.parts:
                graph[module_name(path, root)[0]] = (path, imports_of(path, root))
    return graph


def room(name: str) -> str | None:
    """The room of bitemesh that the module ``name`` belongs to (``"bitemesh"``: the package's own __init__, whose
    names load lazily), or None outside bitemesh."""
    parts = name.split(".")
    if parts[0] != "bitemesh":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in ROOMS else "bitemesh"


def top(name: str) -> str:
    return name.split(".")[0]


def violations(graph: dict, importers, forbidden) -> list[str]:
    """"importer (file:line) imports imported" for each import of a forbidden module by one of the importers."""
    return [f"{importer} ({where(path)}:{line}) imports {imported}"
            for importer, (path, imports) in sorted(graph.items()) if importers(importer)
            for imported, line in imports if imported != importer and forbidden(imported)]


def where(path: Path) -> str:
    """The file, from the repository's root (a file elsewhere: its name)."""
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else path.name


def outside(*rooms: str):
    """Forbidden: any module of bitemesh outside ``rooms``."""
    return lambda imported: room(imported) is not None and room(imported) not in rooms


def in_room(*rooms: str):
    return lambda name: room(name) in rooms


def is_slicer_module(name: str) -> bool:
    return top(name) in ("BiteMesh", "BiteMeshLib")


#: the rooms, what each may import and the front door's names: docs/layers.toml (which docs/architecture.md draws).
LAYERS = tomllib.loads((ROOT / "docs" / "layers.toml").read_text())
BY_KIND = frozenset(LAYERS["front_door"]["by_kind"])


def room_rule(name: str, allowed: list) -> tuple:
    """The rule of a room of docs/layers.toml: its modules import no room of bitemesh outside ``allowed``."""
    importers = is_slicer_module if name == "slicer" else in_room(name)
    rooms = set(allowed) | ({name} if name != "slicer" else set())
    return importers, lambda imported: room(imported) is not None and room(imported) not in rooms


#: rule -> (which modules it constrains, what they must not import)
RULES = {
    **{f"{name} imports only {', '.join(spec['imports']) or 'itself'}": room_rule(name, spec["imports"])
       for name, spec in LAYERS["rooms"].items() if name != "bitemesh"},   # the package's names load lazily
    "core imports no VTK": (in_room("core"), lambda imported: top(imported) in VTK),
    "the package's __init__ imports neither cli nor paraview_plugin":
        (in_room("bitemesh"), lambda imported: room(imported) in ("cli", "paraview_plugin")),
    "nothing outside cli imports bitemesh.cli":
        (lambda name: room(name) != "cli", lambda imported: room(imported) == "cli"),
    "nothing outside paraview_plugin imports bitemesh.paraview_plugin":
        (lambda name: room(name) != "paraview_plugin", lambda imported: room(imported) == "paraview_plugin"),
    "only paraview_plugin imports paraview":
        (lambda name: room(name) != "paraview_plugin", lambda imported: top(imported) == "paraview"),
    "only the front door tells inputs apart: no other room above core, io and labelmap calls a source by kind":
        (lambda name: room(name) not in ("meshing", "core", "io", "labelmap", None) or is_slicer_module(name),
         lambda imported: imported in BY_KIND),
}
#: rule -> why it fails today (an arrow of the current code that points up: reported, to be fixed in filters/)
KNOWN_VIOLATIONS: dict = {}


@pytest.fixture(scope="module")
def graph() -> dict:
    """The import graph of the package and of the Slicer module."""
    return import_graph((FILTERS / "bitemesh", FILTERS), (SLICER_MODULE, SLICER_MODULE))


# --- the rules ------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("rule", [pytest.param(rule, marks=pytest.mark.xfail(reason=KNOWN_VIOLATIONS[rule],
                                                                             strict=True))
                                  if rule in KNOWN_VIOLATIONS else rule for rule in RULES])
def test_no_arrow_points_up(graph, rule):
    importers, forbidden = RULES[rule]
    assert any(importers(name) for name in graph), f"no module is constrained by {rule!r}: the rooms moved?"
    found = violations(graph, importers, forbidden)
    assert not found, f"{rule}:\n  " + "\n  ".join(found)


def test_the_graph_holds_every_room_and_the_slicer_module(graph):
    assert {room(name) for name in graph} >= {"bitemesh", "core", "convert", "io", "labelmap", "algorithms", "cli",
                                               "paraview_plugin"}
    assert "bitemesh.core.sources.points" in graph and "BiteMeshLib.logic" in graph and "BiteMesh" in graph
    # the Slicer module does use bitemesh (else the rule above would hold trivially)
    slicer_imports = {imported for name, (_, imports) in graph.items() if is_slicer_module(name)
                      for imported, _ in imports}
    assert {"bitemesh.core", "bitemesh.io", "bitemesh.convert"} <= {".".join(m.split(".")[:2])
                                                                   for m in slicer_imports}


def test_every_entry_by_kind_exists_and_the_front_door_uses_them(graph):
    """The names the front-door rule forbids are real (a rename would make the rule hold trivially), and the front
    door is where they are called."""
    import importlib
    for name in BY_KIND:
        module, attribute = name.rsplit(".", 1)
        assert hasattr(importlib.import_module(module), attribute), name
    assert {"bitemesh.core.sources.points.run", "bitemesh.core.sources.contours.run.run_labelled",
            "bitemesh.labelmap.mesh_label_grid", "bitemesh.io.looks_labelled"} <= \
        {imported for imported, _ in graph["bitemesh.meshing"][1]}


def test_the_package_names_load_from_the_rooms_below_it():
    """``bitemesh.mesh``, ``bitemesh.batch`` and ``from bitemesh import PointsToImplicit`` load their module on first
    use, by a name that ast cannot read (importlib.import_module of a table entry): the table names only the rooms
    docs/layers.toml lets the package import."""
    assert bitemesh._NAMES and {room(f"bitemesh.{module}") for module, _ in bitemesh._NAMES.values()} <= \
        set(LAYERS["rooms"]["bitemesh"]["imports"])


def test_every_room_of_the_package_is_in_the_layers():
    """A new subpackage or top-level module has its place (and its rule) in docs/layers.toml."""
    rooms = ROOMS | {"bitemesh", "slicer"}
    assert rooms == set(LAYERS["rooms"]), rooms ^ set(LAYERS["rooms"])


def test_the_reader_finds_relative_imports_and_those_inside_functions(tmp_path):
    """The graph reader on a made-up package: relative imports resolved, imports inside functions and
    ``from bitemesh import cli`` found; the core rule then fails, naming the module and what it imports."""
    core = tmp_path / "bitemesh" / "core"
    core.mkdir(parents=True)
    (tmp_path / "bitemesh" / "__init__.py").write_text("")
    (core / "__init__.py").write_text("from .a import f\n")
    (core / "a.py").write_text("from . import b\nfrom ..io import reader\n\n\ndef f():\n    import bitemesh.cli.mesh\n"
                               "    from bitemesh import paraview_plugin\n    from importlib import import_module\n"
                               "    return import_module('bitemesh.convert')\n")
    made_up = import_graph((tmp_path / "bitemesh", tmp_path))
    assert {imported for imported, _ in made_up["bitemesh.core"][1]} == {"bitemesh.core.a", "bitemesh.core.a.f"}
    imported = {name for name, _ in made_up["bitemesh.core.a"][1]}
    assert {"bitemesh.core", "bitemesh.core.b", "bitemesh.io", "bitemesh.io.reader", "bitemesh.cli.mesh",
            "bitemesh.paraview_plugin", "bitemesh.convert"} <= imported
    found = violations(made_up, *RULES["core imports only itself"])
    assert found == ["bitemesh.core.a (a.py:2) imports bitemesh.io",
                     "bitemesh.core.a (a.py:2) imports bitemesh.io.reader",
                     "bitemesh.core.a (a.py:6) imports bitemesh.cli.mesh", "bitemesh.core.a (a.py:7) imports bitemesh",
                     "bitemesh.core.a (a.py:7) imports bitemesh.paraview_plugin",
                     "bitemesh.core.a (a.py:9) imports bitemesh.convert"], found


# --- at run time ----------------------------------------------------------------------------------------------------


def test_every_core_module_imports_without_vtk():
    modules = [m.name for m in pkgutil.walk_packages(bitemesh.core.__path__, "bitemesh.core.")]
    assert {"bitemesh.core.sources.points", "bitemesh.core.sources.contours.run"} <= set(modules)
    code = ("import sys; sys.modules['vtkmodules'] = None; sys.modules['vtk'] = None\n"
            f"for name in {modules!r}: __import__(name)\n"
            "loaded = [m for m, module in sys.modules.items() if module is not None]\n"
            "assert not any(m.startswith(('vtk', 'bitemesh.io', 'bitemesh.cli')) for m in loaded), loaded")
    subprocess.run([sys.executable, "-c", code], check=True, env={"PYTHONPATH": str(FILTERS)})


def module_level_imports(path: Path, root: Path) -> set:
    """The bitemesh modules the file imports when it is imported: its module-level imports, not those inside a
    function (a lazy import is how a module may name one that imports it)."""
    name, package = module_name(path, root)
    found = set()
    for node in ast.parse(path.read_text(), filename=str(path)).body:
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = resolve(name, package, node.level, node.module)
            found |= {base} | {f"{base}.{alias.name}" for alias in node.names if alias.name != "*"}
    return {imported for imported in found if top(imported) == "bitemesh" and imported != name}


def test_no_import_cycle_at_module_level():
    """No module of bitemesh imports, at module level, one that (through others) imports it back: such a cycle
    works or fails by which module is imported first."""
    modules = {module_name(path, FILTERS)[0]: path for path in sorted((FILTERS / "bitemesh").rglob("*.py"))
               if "__pycache__" not in path.parts}
    edges = {name: sorted(imported for imported in module_level_imports(path, FILTERS) if imported in modules)
             for name, path in modules.items()}
    cycles, state = [], {}

    def visit(name, trail):
        state[name] = "open"
        for imported in edges[name]:
            if state.get(imported) == "open":
                cycles.append(" -> ".join(trail[trail.index(imported):] + [imported]))
            elif imported not in state:
                visit(imported, trail + [imported])
        state[name] = "done"

    for name in modules:
        if name not in state:
            visit(name, [name])
    assert not cycles, "module-level import cycles:\n" + "\n".join(cycles)
