"""The beating heart as one 4-D space-time mesh: a picture of its instants, each cut open along the long axis.

    bitemesh mesh GPFile_0*.txt --space-time -o cycle.npz       # the cycle's 4-D mesh, its instants in cycle.pvd
    python examples/space_time_heart.py cycle.pvd -o space_time_heart.png --frames 0 4 8 12

Each instant chosen (a 3-D mesh cut out of the 4-D one at its frame's time, written beside the .pvd) is drawn side
by side, the cells on one side of a plane through the long axis (the cut faces show the walls and the cavities),
the same plane, camera and scale for all, with its frame number and volume (ml: coordinates in mm).

Plain VTK: every VTK import comes from ``vtkmodules``.  Run it with bitemesh installed, or from a clone with
``PYTHONPATH=filters``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import vtkmodules.vtkInteractionStyle
import vtkmodules.vtkRenderingFreeType
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderer, vtkRenderWindow, vtkTextActor)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vtk_pipeline import prefer_headless_egl, write_png  # noqa: E402


def instants(series: Path) -> list:
    """The .vtu files a ParaView .pvd time series lists, in its order."""
    return [series.with_name(entry.get("file")) for entry in ElementTree.parse(series).getroot().iter("DataSet")]


def axes(points: np.ndarray):
    """(centre (3,), long axis (3,), across (3,)): the points' centre and their two widest principal directions."""
    centre = points.mean(axis=0)
    directions = np.linalg.svd(points - centre, full_matrices=False)[2]
    return centre, directions[0], directions[1]


def cut_open(mesh, centre, normal) -> tuple:
    """(points, triangles): the boundary faces of the cells whose centroid lies on the positive side of the plane
    through ``centre`` with ``normal``."""
    cells = mesh.cells[(mesh.points[mesh.cells].mean(axis=1) - centre) @ normal > 0]
    faces = np.sort(np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]], cells[:, [0, 2, 3]],
                                    cells[:, [1, 2, 3]]]), axis=1)
    unique, counts = np.unique(faces, axis=0, return_counts=True)
    return mesh.points, unique[counts == 1]


def render(paths: list, frames: list, output: str, size=(1250, 440)) -> None:
    import bitemesh
    from bitemesh.convert import cell_array, vtk_points
    from bitemesh.core.mesh.simplicial import signed_measures

    meshes = [bitemesh.read(paths[frame]) for frame in frames]
    centre, long_axis, across = axes(meshes[0].points)
    view = np.cross(long_axis, across)
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*size)
    camera = None
    for number, (frame, mesh) in enumerate(zip(frames, meshes)):
        renderer = vtkRenderer()   # one viewport an instant, one camera for all: the same place and scale
        renderer.SetViewport(number / len(frames), 0.0, (number + 1) / len(frames), 1.0)
        renderer.SetBackground(1.0, 1.0, 1.0)
        mapper = vtkPolyDataMapper()
        points, triangles = cut_open(mesh, centre, view)
        surface = vtkPolyData()
        surface.SetPoints(vtk_points(points))
        surface.SetPolys(cell_array(triangles))
        mapper.SetInputData(surface)
        actor = vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().SetColor(0.80, 0.35, 0.35)
        renderer.AddActor(actor)
        volume = float(signed_measures(mesh.points, mesh.cells).sum()) / 1000.0
        label = vtkTextActor()
        label.SetInput(f"frame {frame}: {volume:.0f} ml")
        label.GetTextProperty().SetColor(0.1, 0.1, 0.1)
        label.GetTextProperty().SetFontSize(18)
        label.SetPosition(15, 15)
        renderer.AddViewProp(label)
        if camera is None:
            camera = renderer.GetActiveCamera()
            camera.SetFocalPoint(*centre)
            camera.SetPosition(*(centre - 1000.0 * view))   # facing the cut faces
            camera.SetViewUp(*long_axis)
            renderer.ResetCamera()
            camera.Zoom(0.95)
        else:
            renderer.SetActiveCamera(camera)
        window.AddRenderer(renderer)
        print(f"frame {frame}: {len(mesh.cells):,} cells, {volume:.1f} ml")
    write_png(window, output)
    print(f"wrote {output}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("series", type=Path, help="the .pvd of the instants (written by bitemesh mesh --space-time)")
    parser.add_argument("-o", "--output", default="space_time_heart.png", help="the PNG to write")
    parser.add_argument("--frames", type=int, nargs="+", default=[0, 4, 8, 12], help="the instants drawn")
    args = parser.parse_args(argv)
    prefer_headless_egl()
    paths = instants(args.series)
    wrong = [frame for frame in args.frames if not 0 <= frame < len(paths)]
    if wrong:
        raise SystemExit(f"--frames {wrong[0]}: the series has frames 0 to {len(paths) - 1}")
    render(paths, args.frames, args.output)


if __name__ == "__main__":
    main()
