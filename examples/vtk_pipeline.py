"""Scattered points -> tetrahedral mesh with the five bitemesh VTK filters, and a picture of a cut through it.

    python examples/vtk_pipeline.py                        # the die of the paper's Figure 4, sampled as points
    python examples/vtk_pipeline.py points.xyz -o cut.png  # your points (.xyz .csv .vtp .ply .stl ...)

The pipeline is the paper's: PointsToImplicit -> BitingSampler -> DelaunayTetra -> SpuriousCellFilter (which
also takes the implicit image on its port 1) -> QualityFilter.  The script prints the quality summary that
QualityFilter leaves in the mesh's field data, and renders offscreen (no display needed) the cells on one side of
the plane x = centre, coloured by their radius ratio, as in Figure 3c of the paper, to a PNG file.

Plain VTK: every VTK import comes from ``vtkmodules``.  Run it with bitemesh installed, or from a clone with
``PYTHONPATH=filters``.
"""
from __future__ import annotations

import argparse
import ctypes.util
import os
import sys

import numpy as np

# The rendering classes come from object factories: these imports register the OpenGL implementations, the
# interactor styles and the text rendering (the scalar bar's labels).
import vtkmodules.vtkInteractionStyle
import vtkmodules.vtkRenderingFreeType
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkLookupTable, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPlane, vtkPolyData
from vtkmodules.vtkFiltersExtraction import vtkExtractGeometry
from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter
from vtkmodules.vtkIOImage import vtkPNGWriter
from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
from vtkmodules.vtkRenderingCore import (vtkActor, vtkDataSetMapper, vtkPolyDataMapper, vtkRenderer,
                                         vtkRenderWindow, vtkWindowToImageFilter)

from bitemesh import BitingSampler, DelaunayTetra, PointsToImplicit, QualityFilter, SpuriousCellFilter


def scattered_points(path: str | None, spacing: float):
    """(points, normals or None): read from ``path``, or sampled on the die's surface ``spacing`` apart."""
    if path:
        from bitemesh.io import read_points
        return read_points(path)
    from bitemesh.core.shapes import die, sample_surface
    return sample_surface(die(), spacing, noise=0.002, seed=1)


def to_polydata(points: np.ndarray, normals: np.ndarray | None) -> vtkPolyData:
    """Points (and a ``Normals`` point array) as the vtkPolyData PointsToImplicit takes."""
    xyz = np.zeros((len(points), 3))
    xyz[:, :points.shape[1]] = points
    polydata = vtkPolyData()
    polydata.SetPoints(vtkPoints())
    polydata.GetPoints().SetData(numpy_to_vtk(xyz, deep=True))
    if normals is not None:
        array = np.zeros((len(normals), 3))
        array[:, :normals.shape[1]] = normals
        vtk_normals = numpy_to_vtk(array, deep=True)
        vtk_normals.SetName("Normals")
        polydata.GetPointData().AddArray(vtk_normals)
    return polydata


def mesh_pipeline(source: vtkPolyData, cells: int) -> QualityFilter:
    """The five filters, connected; nothing runs until ``update()``."""
    implicit = PointsToImplicit()
    implicit.SetInputData(source)
    implicit.SetCells(cells)   # the grid I is laid out for R; BitingSampler takes that R from the image
    biting = BitingSampler()
    biting.SetInputConnection(implicit.GetOutputPort())
    delaunay = DelaunayTetra()
    delaunay.SetInputConnection(biting.GetOutputPort())
    spurious = SpuriousCellFilter()
    spurious.SetInputConnection(0, delaunay.GetOutputPort())
    spurious.SetInputConnection(1, implicit.GetOutputPort())  # the implicit image on port 1
    quality = QualityFilter()
    quality.SetInputConnection(spurious.GetOutputPort())
    return quality


def print_quality(mesh, histogram) -> None:
    """The summary QualityFilter puts in the field data, and its radius-ratio histogram (port 1, a vtkTable)."""
    field_data = mesh.GetFieldData()
    for index in range(field_data.GetNumberOfArrays()):
        array = field_data.GetArray(index)
        print(f"{array.GetName():>20}  {array.GetValue(0):.6g}")
    starts, counts = histogram.GetColumnByName("BinStart"), histogram.GetColumnByName("Count")
    largest = max(counts.GetValue(row) for row in range(histogram.GetNumberOfRows()))
    print("radius ratio histogram:")
    for row in range(histogram.GetNumberOfRows()):
        count = counts.GetValue(row)
        print(f"  {starts.GetValue(row):4.2f}  {count:7d}  {'#' * round(40 * count / max(largest, 1))}")


def prefer_headless_egl() -> None:
    """Without a display, VTK (9.4 and later) first tries X, warns "bad X server connection", then falls back to
    EGL: ask for EGL at once where its library is installed (Debian: libegl1 and libgl1-mesa-dri)."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") and ctypes.util.find_library("EGL"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def render_cut(mesh, path: str, size=(800, 600)) -> None:
    """Render offscreen the cells on the x < centre side of the mesh (whole cells, as a crinkle cut), coloured by
    their radius ratio on a 0..1 scale, with a faint outline of the whole surface, and write a PNG."""
    bounds = mesh.GetBounds()
    centre = [(bounds[2 * axis] + bounds[2 * axis + 1]) / 2 for axis in range(3)]
    plane = vtkPlane()
    plane.SetOrigin(centre)
    plane.SetNormal(1.0, 0.0, 0.0)
    cut = vtkExtractGeometry()  # keeps whole cells: the tetrahedra show as they are
    cut.SetInputData(mesh)
    cut.SetImplicitFunction(plane)
    cut.ExtractInsideOn()  # the side where the plane's function is negative: x < centre
    cut.ExtractBoundaryCellsOn()  # and the cells the plane crosses

    table = vtkLookupTable()
    table.SetHueRange(0.0, 0.667)  # red (poor, Q = 0) to blue (regular, Q = 1)
    table.SetTableRange(0.0, 1.0)
    table.Build()
    mapper = vtkDataSetMapper()
    mapper.SetInputConnection(cut.GetOutputPort())
    mapper.SetScalarModeToUseCellFieldData()
    mapper.SelectColorArray("RadiusRatio")
    mapper.SetLookupTable(table)
    mapper.SetScalarRange(0.0, 1.0)
    cells = vtkActor()
    cells.SetMapper(mapper)
    cells.GetProperty().EdgeVisibilityOn()
    cells.GetProperty().SetEdgeColor(0.15, 0.15, 0.15)

    surface = vtkDataSetSurfaceFilter()
    surface.SetInputData(mesh)
    surface_mapper = vtkPolyDataMapper()
    surface_mapper.SetInputConnection(surface.GetOutputPort())
    surface_mapper.ScalarVisibilityOff()
    outline = vtkActor()
    outline.SetMapper(surface_mapper)
    outline.GetProperty().SetColor(0.8, 0.8, 0.8)
    outline.GetProperty().SetOpacity(0.15)

    bar = vtkScalarBarActor()
    bar.SetLookupTable(table)
    bar.SetTitle("radius ratio")
    bar.SetNumberOfLabels(6)
    bar.SetLabelFormat("%.1f")
    bar.UnconstrainedFontSizeOn()
    for text, font_size in ((bar.GetTitleTextProperty(), 18), (bar.GetLabelTextProperty(), 16)):
        text.SetFontSize(font_size)
        text.SetColor(0.0, 0.0, 0.0)
        text.BoldOff()
        text.ItalicOff()
        text.ShadowOff()

    renderer = vtkRenderer()
    renderer.AddActor(cells)
    renderer.AddActor(outline)
    renderer.AddViewProp(bar)
    renderer.SetBackground(1.0, 1.0, 1.0)
    camera = renderer.GetActiveCamera()
    camera.SetFocalPoint(centre)
    camera.SetPosition(centre[0] + 3.0, centre[1] - 1.6, centre[2] + 1.4)  # looking at the cut face
    camera.SetViewUp(0.0, 0.0, 1.0)
    renderer.ResetCamera()

    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*size)
    window.AddRenderer(renderer)
    write_png(window, path)


def write_png(window, path: str) -> None:
    """Render the offscreen ``window`` and write what it shows to the PNG ``path``."""
    window.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.ReadFrontBufferOff()
    writer = vtkPNGWriter()
    writer.SetFileName(path)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()
    window.Finalize()

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("points", nargs="?", help="scattered points to read (default: sample the die)")
    parser.add_argument("-o", "--output", default="bitemesh_cut.png", help="the PNG to write")
    parser.add_argument("--cells", type=int, default=10000, help="cells to aim for (default 10000)")
    parser.add_argument("--spacing", type=float, default=0.04, help="sample spacing on the die (default 0.04)")
    args = parser.parse_args(argv)

    points, normals = scattered_points(args.points, args.spacing)
    print(f"{len(points)} scattered points{' with normals' if normals is not None else ''}")
    quality = mesh_pipeline(to_polydata(points, normals), args.cells)
    mesh = quality.update()  # raises bitemesh.InvalidInputError (naming the parameter) on bad input
    print_quality(mesh, quality.GetOutputDataObject(1))
    prefer_headless_egl()
    render_cut(mesh, args.output)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
