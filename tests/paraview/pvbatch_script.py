"""What tests/paraview/test_pvbatch.py runs inside pvbatch (ParaView's Python with its VTK 9.2, Debian's numpy/scipy).

    pvbatch pvbatch_script.py --plugin filters/bitemesh/paraview_plugin.py --points sphere.csv --out DIR
        [--cells 3000] [--radius 0.15] [--grid-spacing 0.03] [--seed 0]
        [--labelled shell.vtp [--domain "EPI - LV_ENDO - RV_ENDO"] [--bad-domain "EPI - AORTA"] [--labelled-cells 6000]]
        [--gpfile GPFile_000.txt]

Loads the plugin, reads the scattered points as a ParaView user would (CSV Reader, Table To Points), meshes them
with "Volume Mesh From Points" and with the five-filter chain, and compares each with the plain VTK filters and
``bitemesh.run`` on the same points and parameters in this same process (they must be equal, bit for bit).  With
``--labelled``, meshes labelled contour points (a VTP with ``Label`` and ``Slice`` arrays, read with ParaView's
reader) with "Volume Mesh From Points" and the given Domain (base plane none), after trying the bad domain.  With
``--gpfile``, the README's path for biv-me guide points (a table, then Fibre Field, Ventricular Coordinates and
Template Fit), compared with run_labelled and with_fibres here.  Writes
``DIR/one_shot.vtu``, ``DIR/chain.vtu``, ``DIR/labelled.vtu`` and ``DIR/results.json``: every check by name with
``ok`` and a detail, and the facts the test compares again in its own Python.  No check stops the script: the test
reports each one.  The record-keeping, the mesh comparisons and the checks of the environment and of the generated
properties are in pvbatch_checks.py beside this script (pvbatch, like python, puts the script's folder first on
sys.path).
"""
from __future__ import annotations

import inspect

# ParaView 5.11 imports inspect.getargspec (gone in Python 3.11) when it loads a Python plugin.
if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec

import argparse
import json
import sys
import time
import traceback
from pathlib import Path

from bitemesh.core.sources.points import run as points_run
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.fem.fibres import FIBRE_ARRAYS, with_fibres
import bitemesh
import numpy as np
from bitemesh import algorithms
from bitemesh.convert import nodes_to_polydata, plan_of, tag_names_of, unstructured_to_mesh, with_polydata_tags
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.parameters import BitingParameters, ImplicitParameters, OptimizeParameters, SpuriousParameters
from bitemesh.core.mesh.validity import boundary_euler_characteristic, count_boundary_components
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.io import read_labelled_points
from paraview import servermanager, simple
from paraview.simple import CSVReader, LoadPlugin, ProgrammableFilter, SaveData, TableToPoints, TrivialProducer
from distances import boundary_hausdorff
from pvbatch_checks import (check, checks, environment, facts, guarded, properties, same_mesh, timed, updated,
                            valid_sphere)
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData

#: bitemesh class name -> the plugin's filter in paraview.simple
FILTERS = {"MeshFromPoints": "VolumeMeshFromPoints", "PointsToImplicit": "PointsToImplicit",
           "BitingSampler": "BitingSampler", "DelaunayTetra": "DelaunayTetra",
           "SpuriousCellFilter": "SpuriousCellFilter", "QualityFilter": "QualityFilter", "FibreField": "FibreField",
           "VentricularCoordinates": "VentricularCoordinates",
           "TemplateFit": "TemplateFit"}
#: the Programmable Filter script of docs/vtk-paraview-slicer.md (Output Data Set Type: vtkUnstructuredGrid);
#: CELLS is substituted.
PROGRAMMABLE_SCRIPT = """
import bitemesh
from bitemesh.convert import mesh_to_unstructured
from vtkmodules.util.numpy_support import vtk_to_numpy

points = vtk_to_numpy(self.GetInput().GetPoints().GetData())     # (n, 3): the input's points
mesh = bitemesh.mesh(points, cells=CELLS).mesh                     # any option of bitemesh.Options
self.GetOutput().ShallowCopy(mesh_to_unstructured(mesh))
"""


@guarded("one-shot filter")
def one_shot(points_proxy, xyz: np.ndarray, args, out: Path) -> None:
    proxy = simple.VolumeMeshFromPoints(Input=points_proxy, Cells=args.cells, Seed=args.seed)
    grid = timed("Volume Mesh From Points", proxy)
    mesh = unstructured_to_mesh(grid)
    valid_sphere("one-shot", mesh)
    SaveData(str(out / "one_shot.vtu"), proxy=proxy)

    clock = time.perf_counter()
    result = points_run(xyz, None, ImplicitParameters(), BitingParameters(cells=args.cells, seed=args.seed),
                          SpuriousParameters())
    facts["seconds"]["bitemesh.run (same process)"] = round(time.perf_counter() - clock, 3)
    same_mesh("one-shot = bitemesh.run", mesh, result.mesh)
    radius = plan_of(grid)["Radius"]
    check("one-shot field data Radius = run's R", radius == result.radius, f"{radius} vs {result.radius}")
    for key, values in result.mesh.cell_data.items():
        check(f"one-shot cell data {key} = run's", np.array_equal(mesh.cell_data.get(key), values), key)

    ports = [proxy.GetOutputPortName(port) for port in range(proxy.GetNumberOfOutputPorts())]
    check("one-shot surfaces: the output ports are Mesh and Surfaces", ports == ["Mesh", "Surfaces"], ports)
    tagged = with_polydata_tags(mesh, updated(proxy, 1))
    check("one-shot surfaces: the tagged facets, their tags and names = run's",
          np.array_equal(tagged.facets, result.mesh.facets)
          and np.array_equal(tagged.facet_tags, result.mesh.facet_tags) and tagged.tag_names == result.mesh.tag_names,
          tagged.tag_names)

    vtk_filter = algorithms.MeshFromPoints()
    vtk_filter.SetInputData(nodes_to_polydata(xyz))
    vtk_filter.SetCells(args.cells)
    vtk_filter.SetSeed(args.seed)
    same_mesh("one-shot = plain VTK MeshFromPoints", mesh, unstructured_to_mesh(vtk_filter.update()))
    facts["one_shot"] = {"points": len(mesh.points), "cells": len(mesh.cells), "radius": radius,
                         "file": "one_shot.vtu"}


@guarded("five-filter chain")
def chain(points_proxy, xyz: np.ndarray, args, out: Path) -> None:
    margin = 3 * args.grid_spacing
    implicit = simple.PointsToImplicit(Input=points_proxy, GridSpacing=args.grid_spacing, Margin=margin)
    nodes = simple.BitingSampler(Input=implicit, Radius=args.radius, Seed=args.seed)
    tetra = simple.DelaunayTetra(Input=nodes)
    domain = simple.SpuriousCellFilter(Mesh=tetra, Implicit=implicit)
    quality = simple.QualityFilter(Input=domain, Bins=10)
    clock = time.perf_counter()
    grid = updated(quality, 0)
    facts["seconds"]["five-filter chain"] = round(time.perf_counter() - clock, 3)
    mesh = unstructured_to_mesh(grid)
    valid_sphere("chain", mesh)
    SaveData(str(out / "chain.vtu"), proxy=simple.OutputPort(quality, 0))

    image = updated(implicit)
    check("chain: implicit image has the grid spacing", np.allclose(image.GetSpacing(), args.grid_spacing),
          image.GetSpacing())
    names = [quality.GetOutputPortName(port) for port in range(quality.GetNumberOfOutputPorts())]
    check("chain: Quality Filter's output ports are Mesh and Histogram", names == ["Mesh", "Histogram"], names)
    table = updated(quality, 1)
    counts = numpy_support.vtk_to_numpy(table.GetColumnByName("Count")) if table.GetColumnByName("Count") else []
    check("chain: histogram table on port 1 (10 bins, every cell counted)",
          table.IsA("vtkTable") and len(counts) == 10 and int(np.sum(counts)) == len(mesh.cells),
          f"{table.GetClassName()}, {len(counts)} rows, {int(np.sum(counts))} cells")

    # the same steps as plain VTK filters (ParaView's VTK, outside any proxy)
    source = nodes_to_polydata(xyz)
    f1 = algorithms.PointsToImplicit()
    f1.SetInputData(source)
    f1.SetGridSpacing(args.grid_spacing)
    f1.SetMargin(margin)
    f2 = algorithms.BitingSampler()
    f2.SetInputConnection(f1.GetOutputPort())
    f2.SetRadius(args.radius)
    f2.SetSeed(args.seed)
    f3 = algorithms.DelaunayTetra()
    f3.SetInputConnection(f2.GetOutputPort())
    f4 = algorithms.SpuriousCellFilter()
    f4.SetInputConnection(0, f3.GetOutputPort())
    f4.SetInputConnection(1, f1.GetOutputPort())
    f5 = algorithms.QualityFilter()
    f5.SetInputConnection(f4.GetOutputPort())
    plain = unstructured_to_mesh(f5.update())
    same_mesh("chain = plain VTK filters", mesh, plain)
    for key in plain.cell_data:
        check(f"chain cell data {key} = plain VTK's", np.array_equal(mesh.cell_data.get(key), plain.cell_data[key]),
              key)
    result = points_run(xyz, None, ImplicitParameters(grid_spacing=args.grid_spacing, margin=margin),
                          BitingParameters(radius=args.radius, seed=args.seed), SpuriousParameters(),
                          optimize=OptimizeParameters(optimize=0))   # the five filters: the plain method
    # bitemesh.run meshes the points centred and scaled to unit size, the chain in the points' own frame (its image
    # is in user coordinates): the grids differ in their rounding, so the meshes are equivalent, not equal
    volumes = [float(np.sum(signed_measures(m.points, m.cells))) for m in (mesh, result.mesh)]
    check("chain ~ bitemesh.run with the same radius, grid spacing and margin (cells within 5 %, volume 1 %)",
          abs(len(mesh.cells) / len(result.mesh.cells) - 1) < 0.05 and abs(volumes[0] / volumes[1] - 1) < 0.01,
          f"{len(mesh.cells)} vs {len(result.mesh.cells)} cells, volume {volumes[0]:.4f} vs {volumes[1]:.4f}")
    # and the same shape, not only the same size: the boundaries within half a radius of each other (they may
    # differ by a node bitten or not, which moves the surface by less than a cell; measured 0.075 R), and the same
    # boundary topology
    distance = boundary_hausdorff(mesh, result.mesh)
    check("chain ~ bitemesh.run: boundaries within 0.5 R (symmetric Hausdorff distance, node to surface)",
          distance < 0.5 * args.radius, f"{distance:.4f} = {distance / args.radius:.3f} R")
    topologies = [(count_boundary_components(m), boundary_euler_characteristic(m)) for m in (mesh, result.mesh)]
    check("chain ~ bitemesh.run: the same boundary components and Euler characteristic",
          topologies[0] == topologies[1], f"(components, euler) {topologies[0]} vs {topologies[1]}")
    facts["chain"] = {"points": len(mesh.points), "cells": len(mesh.cells), "file": "chain.vtu"}


@guarded("bad parameter")
def bad_parameter(points_proxy, args) -> None:
    """A negative radius: an error naming radius, an empty output, no crash; the proxy works once fixed."""
    proxy = simple.VolumeMeshFromPoints(Input=points_proxy, Radius=-2.0, Seed=args.seed)   # -1 is automatic
    grid = updated(proxy)
    error = proxy.GetClientSideObject().last_error
    check("negative radius: error names radius", error is not None and "radius" in str(error), repr(error))
    check("negative radius: empty output", grid.GetNumberOfCells() == 0, f"{grid.GetNumberOfCells()} cells")
    proxy.Radius = -1.0  # automatic again
    proxy.Cells = 500
    grid = updated(proxy)
    check("negative radius then automatic: a mesh again",
          grid.GetNumberOfCells() > 0 and proxy.GetClientSideObject().last_error is None,
          f"{grid.GetNumberOfCells()} cells")

    implicit = simple.PointsToImplicit(Input=points_proxy, GridSpacing=0.05)
    nodes = simple.BitingSampler(Input=implicit, Radius=-2.0)
    tetra = simple.DelaunayTetra(Input=nodes)
    domain = simple.SpuriousCellFilter(Mesh=tetra, Implicit=implicit)
    grid = updated(domain)
    sampler, cells_filter = nodes.GetClientSideObject(), domain.GetClientSideObject()
    quiet = [proxy.GetClientSideObject().last_error for proxy in (tetra, domain)]
    check("negative radius in the chain: one error, from BitingSampler; the filters below pass an empty mesh",
          "radius" in str(sampler.last_error) and quiet == [None, None] and grid.GetNumberOfCells() == 0 and
          cells_filter.upstream_error() is sampler.last_error, f"{sampler.last_error!r}; below: {quiet}")
    print("bad-parameter checks done", flush=True)


@guarded("labelled contours")
def labelled(args, out: Path) -> None:
    """Labelled contours from a VTP: a bad Domain is an error naming the surface, then the right one meshes them."""
    reader = simple.XMLPolyDataReader(FileName=[str(args.labelled)])
    arrays = updated(reader).GetPointData()
    kinds = {name: arrays.GetAbstractArray(name).GetClassName() if arrays.GetAbstractArray(name) else None
             for name in ("Label", "Slice")}
    check("labelled: ParaView's reader keeps the Label and Slice arrays",
          kinds["Label"] == "vtkStringArray" and kinds["Slice"] is not None, kinds)
    proxies = {}
    for class_name in "PointsToImplicit", "MeshFromPoints":
        proxy = proxies[class_name] = getattr(simple, FILTERS[class_name])(Input=reader, Domain=args.bad_domain,
                                                                           BasePlane="none")
        labels = [proxy.GetProperty(name).GetXMLLabel() for name in ("Domain", "BasePlane", "MinWall")]
        check(f"labelled: {class_name} shows Domain, Base Plane, Min Wall (-1: automatic)",
              labels == ["Domain", "Base Plane", "Min Wall"] and proxy.MinWall == -1, f"{labels}, {proxy.MinWall}")
        data = updated(proxy)
        error = proxy.GetClientSideObject().last_error
        check(f"labelled bad domain: {class_name} names the unknown surface, empty output",
              "unknown surface" in str(error) and data.GetNumberOfPoints() == 0, repr(error))

    proxy = proxies["MeshFromPoints"]
    proxy.Domain = args.domain
    proxy.Cells = args.labelled_cells
    grid = timed("Volume Mesh From Points, labelled contours", proxy)
    error = proxy.GetClientSideObject().last_error
    check("labelled: the right domain then meshes the contours", error is None and grid.GetNumberOfCells() > 0,
          f"{grid.GetNumberOfCells()} cells, error {error!r}")
    names = tag_names_of(updated(proxy, 1))
    check("labelled: the Surfaces port names the surfaces", names == {"EPI": (1, 2), "LV_ENDO": (2, 2),
                                                                     "RV_ENDO": (3, 2), "MYOCARDIUM": (1, 3)}, names)
    SaveData(str(out / "labelled.vtu"), proxy=proxy)
    facts["labelled"] = {"points": grid.GetNumberOfPoints(), "cells": grid.GetNumberOfCells(),
                         "radius": plan_of(grid)["Radius"], "file": "labelled.vtu"}


@guarded("gpfile")
def gpfile(args, out: Path) -> None:
    """The README's path for a biv-me GPFile: CSV reader (tabs), Table To Points, Volume Mesh From Points with the
    default (empty) Domain."""
    table = simple.CSVReader(FileName=[str(args.gpfile)], FieldDelimiterCharacters="\t")
    points = simple.TableToPoints(Input=table, XColumn="x", YColumn="y", ZColumn="z")
    # a coarse mesh (R about 5 mm): the cavities stay open up to the valves, so no warning
    proxy = getattr(simple, FILTERS["MeshFromPoints"])(Input=points, Cells=args.labelled_cells)
    grid = timed("Volume Mesh From Points, GPFile", proxy)
    error = proxy.GetClientSideObject().last_error
    check("gpfile: the default domain meshes the myocardium", error is None and grid.GetNumberOfCells() > 0,
          f"{grid.GetNumberOfCells()} cells, error {error!r}")
    SaveData(str(out / "gpfile.vtu"), proxy=proxy)
    facts["gpfile"] = {"cells": grid.GetNumberOfCells(), "radius": plan_of(grid)["Radius"], "file": "gpfile.vtu"}
    guide, labels, slices = read_labelled_points(args.gpfile)
    core = run_labelled(guide, labels, slices=slices, biting=BitingParameters(cells=args.labelled_cells)).mesh
    same_mesh("gpfile = run_labelled on the file in this Python", unstructured_to_mesh(grid), core)

    # the README's fibres: Fibre Field on the mesh and its tagged surfaces (the two outputs of the mesher)
    fibres = getattr(simple, FILTERS["FibreField"])(Mesh=proxy, Surfaces=simple.OutputPort(proxy, 1))
    labels = [fibres.GetProperty(name).GetXMLLabel() for name in ("AlphaEndo", "AlphaEpi", "BetaEndo", "BetaEpi")]
    check("gpfile: Fibre Field shows the four angles", labels == ["Alpha Endo", "Alpha Epi", "Beta Endo", "Beta Epi"]
          and (fibres.AlphaEndo, fibres.AlphaEpi) == (40, -50), labels)
    fibred = updated(fibres)
    error = fibres.GetClientSideObject().last_error
    arrays = fibred.GetCellData()
    vectors = {name: numpy_support.vtk_to_numpy(arrays.GetArray(name)) if arrays.GetArray(name) else None
               for name in ("Fibre", "Sheet", "SheetNormal")}
    unit = [v is not None and v.shape == (grid.GetNumberOfCells(), 3) and
            np.allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-6) for v in vectors.values()] == [True] * 3
    check("gpfile: Fibre Field gives unit Fibre, Sheet, SheetNormal per cell and the HelixAngle",
          error is None and unit and arrays.GetArray("HelixAngle") is not None and
          arrays.GetVectors() is not None and arrays.GetVectors().GetName() == "Fibre", f"error {error!r}")
    # a cell at the method's free-wall jump may take the other branch: 0.1 % may differ
    expected = with_fibres(core)[0]
    same_cells = np.array_equal(unstructured_to_mesh(fibred).cells, core.cells)
    differing = {name: share_differing(arrays.GetArray(name), expected.cell_data[name]) for name in FIBRE_ARRAYS}
    check("gpfile: Fibre Field = with_fibres on run_labelled's mesh in this Python",   # (max: ParaView's)
          same_cells and np.max(list(differing.values())) <= 1e-3, f"same cells {same_cells}, differing {differing}")
    SaveData(str(out / "fibres.vtu"), proxy=fibres)
    facts["fibres"] = {"file": "fibres.vtu"}

    # the ventricular coordinates on the same two outputs
    coordinates = getattr(simple, FILTERS["VentricularCoordinates"])(Mesh=proxy, Surfaces=simple.OutputPort(proxy, 1))
    placed = updated(coordinates)
    error = coordinates.GetClientSideObject().last_error
    aha = placed.GetCellData().GetArray("AHA")
    segments = set(numpy_support.vtk_to_numpy(aha).tolist()) if aha is not None else set()
    check("gpfile: Ventricular Coordinates gives the point coordinates and every AHA segment",
          error is None and None not in [placed.GetPointData().GetArray(name) for name in
                                         ("ApicoBasal", "Transmural", "Rotational", "Transventricular")]
          and segments == set(range(18)), f"error {error!r}, segments {sorted(segments)}")   # (all: ParaView's)

    # the elastic template: Template Fit of the fibred mesh and the mesher's surfaces onto the same guide points
    fit = getattr(simple, FILTERS["TemplateFit"])(Mesh=fibres, Surfaces=simple.OutputPort(proxy, 1), Data=points)
    moved = updated(fit)
    error = fit.GetClientSideObject().last_error
    fibre = moved.GetCellData().GetArray("Fibre")
    before, after = (distances_to_facets(guide, mesh.points[boundary_facets(mesh.cells)]).mean()
                     for mesh in (unstructured_to_mesh(grid), unstructured_to_mesh(moved)))
    check("gpfile: Template Fit of the mesh onto its own guide points keeps its cells and unit fibres and brings "
          "the points closer", error is None and moved.GetNumberOfCells() == grid.GetNumberOfCells()
          and fibre is not None and np.allclose(np.linalg.norm(numpy_support.vtk_to_numpy(fibre), axis=1), 1.0,
                                                atol=1e-6) and after < before,
          f"error {error!r}, guide points to the boundary {before:.2f} -> {after:.2f} mm")


def share_differing(array, expected: np.ndarray) -> float:
    """The share of cells whose values in the VTK array differ from ``expected`` (m, ...) by more than 1e-6 (1 if
    the array is absent or has another shape)."""
    if array is None or array.GetNumberOfTuples() != len(expected):
        return 1.0
    values = numpy_support.vtk_to_numpy(array).reshape(len(expected), -1)
    difference = np.abs(values - expected.reshape(len(expected), -1))
    return float(np.mean(difference.max(axis=1) > 1e-6))


@guarded("programmable filter")
def programmable(points_proxy, xyz: np.ndarray, args) -> None:
    """The docs' Programmable Filter script (docs/vtk-paraview-slicer.md) gives bitemesh.mesh's mesh."""
    cells = 1000
    proxy = ProgrammableFilter(Input=points_proxy, OutputDataSetType="vtkUnstructuredGrid",
                               Script=PROGRAMMABLE_SCRIPT.replace("CELLS", str(cells)))
    mesh = unstructured_to_mesh(updated(proxy))
    same_mesh("Programmable Filter = bitemesh.mesh", mesh, bitemesh.mesh(xyz, cells=cells).mesh)


@guarded("label map")
def label_map() -> None:
    """A label map: meshed where ParaView's Python has SimpleITK, else an error that says SimpleITK is needed."""
    image = vtkImageData()
    image.SetDimensions(12, 12, 12)
    ijk = np.indices((12, 12, 12)).reshape(3, -1, order="F").T
    labels = (np.linalg.norm(ijk - 5.5, axis=1) < 4).astype(np.uint8)
    array = numpy_support.numpy_to_vtk(labels, deep=True)
    array.SetName("labels")
    image.GetPointData().SetScalars(array)
    producer = TrivialProducer()
    producer.GetClientSideObject().SetOutput(image)
    proxy = simple.PointsToImplicit(Input=producer)
    result = updated(proxy)
    error = proxy.GetClientSideObject().last_error
    try:
        import SimpleITK  # noqa: F401
        check("label map meshed (SimpleITK present)", error is None and result.GetNumberOfPoints() > 0, repr(error))
        facts["simpleitk"] = True
    except ImportError:
        check("label map without SimpleITK: clear error", error is not None and "SimpleITK" in str(error),
              repr(error))
        facts["simpleitk"] = False


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--plugin", type=Path, required=True)
    parser.add_argument("--points", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--cells", type=int, default=3000)
    parser.add_argument("--radius", type=float, default=0.15)
    parser.add_argument("--grid-spacing", type=float, default=0.03)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--labelled", type=Path, help="a VTP of labelled contour points")
    parser.add_argument("--domain", default="EPI - LV_ENDO - RV_ENDO")
    parser.add_argument("--bad-domain", default="EPI - AORTA")
    parser.add_argument("--labelled-cells", type=int, default=6000)
    parser.add_argument("--gpfile", type=Path, help="a biv-me GPFile, read as a tab-separated table")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    clock = time.perf_counter()
    try:
        LoadPlugin(str(args.plugin))  # adds the filters to paraview.simple
        check("plugin loads", True, args.plugin)
    except Exception:  # noqa: BLE001
        check("plugin loads", False, traceback.format_exc())
    facts["seconds"]["load plugin"] = round(time.perf_counter() - clock, 3)
    environment(args.plugin)

    if checks["plugin loads"]["ok"]:
        missing = [label for label in FILTERS.values() if not hasattr(simple, label)]
        check("six filters in paraview.simple", not missing, missing or sorted(FILTERS.values()))

        reader = CSVReader(FileName=[str(args.points)])
        points_proxy = TableToPoints(Input=reader, XColumn="x", YColumn="y", ZColumn="z")
        xyz = numpy_support.vtk_to_numpy(updated(points_proxy).GetPoints().GetData()).astype(np.float64)
        check("points read by ParaView = the file's",
              np.array_equal(xyz, np.loadtxt(args.points, delimiter=",", skiprows=1)), f"{len(xyz)} points")

        manager = servermanager.vtkSMProxyManager.GetProxyManager().GetActiveSessionProxyManager()
        properties({class_name: manager.NewProxy("filters", f"Bitemesh{class_name}") for class_name in FILTERS})
        one_shot(points_proxy, xyz, args, args.out)
        chain(points_proxy, xyz, args, args.out)
        bad_parameter(points_proxy, args)
        programmable(points_proxy, xyz, args)
        label_map()
        if args.labelled:
            labelled(args, args.out)
        if args.gpfile:
            gpfile(args, args.out)

    facts["seconds"]["pvbatch script"] = round(time.perf_counter() - clock, 3)
    (args.out / "results.json").write_text(json.dumps({"checks": checks, "facts": facts}, indent=1, default=str))
    failed = [name for name, result in checks.items() if not result["ok"]]
    print(f"{len(checks) - len(failed)} checks passed, {len(failed)} failed", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
