"""A real heart's myocardial fibres: biv-me contours -> tagged, fibred mesh -> a picture of a short-axis slab.

    python examples/heart_fibres.py                          # the shipped biv-me patient, -> heart_fibres.png
    python examples/heart_fibres.py heart.vtu -o fibres.png  # a mesh written by ``bitemesh mesh ... --fibres``

Without a mesh file, the script meshes the shipped guide points (biv-me patient 1) as ``bitemesh demo heart
--fibres --cells N`` does (the labelled contours, the four tagged surfaces EPI, LV_ENDO, RV_ENDO, BASE, the
rule-based fibres of Bayer et al. 2012).  It then renders offscreen, seen from the base, the cells of a slab
across the ventricles half-way between the apex and the base, and in each of them a short line along its fibre,
coloured by the helix angle: from about +40 degrees at the endocardium (alpha_endo) to -50 at the epicardium
(alpha_epi).  The long axis is the mean normal of the BASE triangles.

Plain VTK: every VTK import comes from ``vtkmodules``.  Run it with bitemesh installed, or from a clone with
``PYTHONPATH=filters``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import vtkmodules.vtkInteractionStyle
import vtkmodules.vtkRenderingFreeType
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
from vtkmodules.vtkCommonCore import vtkLookupTable, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderer, vtkRenderWindow)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vtk_pipeline import prefer_headless_egl, write_png  # noqa: E402

#: the slab: cells whose centroid lies this far (a fraction of the apex-base length) from its middle plane
SLAB = 0.025
#: the middle plane of the slab, as a fraction of the way from the apex to the base
LEVEL = 0.5


def fibred_heart(path: str | None, cells: int):
    """The mesh (a bitemesh Mesh with facet tags and the fibre arrays): read from ``path``, or meshed."""
    import bitemesh
    if path:
        return bitemesh.read(path)
    from importlib import resources

    with resources.as_file(resources.files("bitemesh") / "data" / "bivme_patient1" / "GPFile_000.txt") as source:
        return bitemesh.mesh(source, cells=cells, fibres=1).mesh


def long_axis(mesh) -> np.ndarray:
    """(3,) unit vector from the apex towards the base: the area-weighted mean normal of the BASE triangles."""
    if "BASE" not in mesh.tag_names or "Fibre" not in mesh.cell_data:
        raise SystemExit("the mesh needs the BASE facet tag and the Fibre cell array: write it with "
                         "bitemesh mesh CONTOURS -o heart.vtu --fibres")
    base = mesh.facets[mesh.facet_tags == mesh.tag_names["BASE"][0]]
    corners = mesh.points[base]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).sum(axis=0)
    return normal / np.linalg.norm(normal)


def slab_lines(mesh, axis: np.ndarray):
    """Line segments (2 s, 3) along the fibres of the cells in the slab, their helix angles (s,), and the slab's
    cells (c, 4)."""
    centroids = mesh.points[mesh.cells].mean(axis=1)
    height = centroids @ axis
    low, high = height.min(), height.max()
    level = low + LEVEL * (high - low)
    chosen = np.abs(height - level) < SLAB * (high - low)
    fibre = mesh.cell_data["Fibre"][chosen]
    half = 0.4 * np.cbrt(np.abs(mesh.cell_data["Volume"][chosen]).mean() * 6 * np.sqrt(2))   # ~0.4 edge length
    ends = np.stack([centroids[chosen] - half * fibre, centroids[chosen] + half * fibre], axis=1).reshape(-1, 3)
    return ends, mesh.cell_data["HelixAngle"][chosen], mesh.cells[chosen]


def polydata(points: np.ndarray, cells: np.ndarray, kind: str) -> vtkPolyData:
    """Lines or triangles (``kind``) on ``points``, as a vtkPolyData."""
    data = vtkPolyData()
    data.SetPoints(vtkPoints())
    data.GetPoints().SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    array = vtkCellArray()
    offsets = np.arange(0, cells.size + 1, cells.shape[1], dtype=np.int64)
    array.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(cells.ravel(), dtype=np.int64), deep=True))
    (data.SetLines if kind == "lines" else data.SetPolys)(array)
    return data


def render(mesh, path: str, size=(1000, 700)) -> None:
    """Write a PNG of the slab's fibres, coloured by helix angle, over the slab's cut faces, seen from the base."""
    axis = long_axis(mesh)
    ends, helix, slab = slab_lines(mesh, axis)
    lines = polydata(ends, np.arange(len(ends)).reshape(-1, 2), "lines")
    colours = numpy_to_vtk(np.ascontiguousarray(helix, dtype=np.float64), deep=True)
    colours.SetName("HelixAngle")
    lines.GetCellData().SetScalars(colours)
    table = vtkLookupTable()
    table.SetHueRange(0.667, 0.0)   # blue (-60 degrees) to red (+60)
    table.SetTableRange(-60.0, 60.0)
    table.Build()
    line_mapper = vtkPolyDataMapper()
    line_mapper.SetInputData(lines)
    line_mapper.SetLookupTable(table)
    line_mapper.SetScalarRange(-60.0, 60.0)
    line_mapper.SetScalarModeToUseCellData()
    fibres = vtkActor()
    fibres.SetMapper(line_mapper)
    fibres.GetProperty().SetLineWidth(2.0)

    faces = np.concatenate([slab[:, [0, 1, 2]], slab[:, [0, 1, 3]], slab[:, [0, 2, 3]], slab[:, [1, 2, 3]]])
    wall_mapper = vtkPolyDataMapper()
    wall_mapper.SetInputData(polydata(mesh.points, faces, "triangles"))
    wall_mapper.ScalarVisibilityOff()
    wall = vtkActor()
    wall.SetMapper(wall_mapper)
    wall.GetProperty().SetColor(0.85, 0.85, 0.85)
    wall.GetProperty().SetOpacity(0.1)

    bar = vtkScalarBarActor()
    bar.SetLookupTable(table)
    bar.SetTitle("helix angle (deg)")
    bar.SetNumberOfLabels(5)
    bar.SetPosition(0.05, 0.1)
    bar.SetWidth(0.8)
    bar.SetHeight(0.8)
    bar.GetTitleTextProperty().SetColor(0.1, 0.1, 0.1)
    bar.GetLabelTextProperty().SetColor(0.1, 0.1, 0.1)
    renderer = vtkRenderer()
    for actor in (wall, fibres):
        renderer.AddActor(actor)
    legend = vtkRenderer()
    legend.SetViewport(0.87, 0.0, 1.0, 1.0)
    legend.SetBackground(1.0, 1.0, 1.0)
    legend.AddActor(bar)
    renderer.SetBackground(1.0, 1.0, 1.0)
    renderer.SetViewport(0.0, 0.0, 0.87, 1.0)   # the bar beside the heart, not over it
    camera = renderer.GetActiveCamera()
    centre = ends.mean(axis=0)
    camera.SetFocalPoint(*centre)
    camera.SetPosition(*(centre + 400.0 * axis))   # from the base, looking towards the apex
    up = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    camera.SetViewUp(*up)
    renderer.ResetCamera()
    camera.Zoom(1.25)
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*size)
    window.AddRenderer(renderer)
    window.AddRenderer(legend)
    write_png(window, path)
    print(f"wrote {path}: {len(helix)} cells of the slab, helix angle {helix.min():.0f} .. {helix.max():.0f} deg")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mesh", nargs="?", help="a .vtu written with --fibres (and its _facets.vtu beside it); "
                                                "default: mesh the shipped biv-me patient")
    parser.add_argument("-o", "--output", default="heart_fibres.png", help="the PNG to write")
    parser.add_argument("--cells", type=int, default=60000, help="cells when meshing the shipped patient")
    args = parser.parse_args(argv)
    prefer_headless_egl()
    render(fibred_heart(args.mesh, args.cells), args.output)


if __name__ == "__main__":
    main()
