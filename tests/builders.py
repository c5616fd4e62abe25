"""The samples the tests build, in one place: analytic shapes sampled on a grid or as scattered points, small meshes
and what the tests measure on meshes (volume, which points a mesh holds), the half-written files a write leaves, the
two-cavity shell's contours, and their VTK forms (point sets, a sphere surface, a label map image, the five filters
connected as the paper's pipeline).  The fixtures shared by several folders are in tests/conftest.py.

Only numpy, scipy and bitemesh.core load with this module; the builders of VTK objects import VTK when called, so
that it loads in every test environment: the core tests', and the Slicer one (slicer-core's VTK, bitemesh on
PYTHONPATH).
"""
from __future__ import annotations

from itertools import permutations
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from bitemesh.core import shapes
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.parameters import OptimizeParameters
from scipy.spatial import cKDTree

#: the paper's plain method, without the MeshOptimizer (on by default): for the tests of another step (reading, the
#: fit, the repair, the interfaces), where the optimizer would only add time; its output is tested on every shape in
#: tests/core/optimize/test_optimize.py, and the default's in the tests that say "default"
PLAIN = OptimizeParameters(optimize=0)

# --- analytic shapes ---------------------------------------------------------------------------------------------


def sampled(shape, spacing):
    """``shape``'s implicit function on a grid of ``spacing``, with a margin of three grid steps."""
    return sample_function(shape.function, shape.lower, shape.upper, spacing, margin=3 * spacing)


#: the semi-axes of :func:`ellipsoid`: three different ones, so that no symmetry hides a wrong axis
ELLIPSOID_AXES = np.array([1.0, 0.7, 0.45])


def ellipsoid() -> shapes.Shape:
    """The ellipsoid of semi-axes :data:`ELLIPSOID_AXES` about the origin, its exact volume as its measure."""
    return shapes.Shape("ellipsoid", lambda p: shapes.ellipsoid_distance(p, np.zeros(3), ELLIPSOID_AXES),
                        -ELLIPSOID_AXES, ELLIPSOID_AXES, 4 / 3 * np.pi * np.prod(ELLIPSOID_AXES), 2)


def sphere_samples(spacing, *, noise=0.0, seed=0):
    """(points, unit outward normals) scattered on the unit sphere, about ``spacing`` apart."""
    return shapes.sample_surface(shapes.sphere(), spacing, noise=noise, seed=seed)


def rotation(axis, degrees) -> np.ndarray:
    """Rotation matrix about ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.radians(degrees)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


# --- small meshes ------------------------------------------------------------------------------------------------


def positively_oriented(points, cells) -> np.ndarray:
    """``cells`` with the first two vertices of each negatively oriented cell swapped."""
    cells = np.array(cells, dtype=np.int64)
    negative = signed_measures(points, cells) < 0
    cells[negative, :2] = cells[negative, 1::-1]
    return cells


def cube_mesh() -> Mesh:
    """The unit cube split into 6 tetrahedra around the diagonal (0,0,0)-(1,1,1), with two cell arrays."""
    points = np.array([[(i >> 0) & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=float)
    cells = []
    for order in permutations(range(3)):
        path, corner = [0], 0
        for axis in order:
            corner |= 1 << axis
            path.append(corner)
        cells.append(path)
    cells = positively_oriented(points, cells)
    data = {"Label": np.array([1, 1, 1, 2, 2, 2], dtype=np.int32), "Quality": np.linspace(0.1, 0.6, 6)}
    return Mesh(points, cells, data)


def volume(mesh) -> float:
    """The mesh's volume (area in 2D): the sum of its cells' signed measures (all positive in a valid mesh)."""
    return float(signed_measures(mesh.points, mesh.cells).sum())


def located(mesh, points, candidates: int | None = 64) -> np.ndarray:
    """(m,) True for each of the points (m, 3), or the one point (3,), that lies in a tetrahedron of ``mesh``
    (within 1e-9 in barycentric coordinates).  Only the ``candidates`` tetrahedra with the nearest centroids are
    tried; None tries every tetrahedron."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    corners = mesh.points[mesh.cells]
    if candidates is None or candidates >= len(corners):
        near = np.broadcast_to(np.arange(len(corners)), (len(points), len(corners)))
    else:
        _, near = cKDTree(corners.mean(axis=1)).query(points, k=candidates)
        near = near.reshape(len(points), candidates)
    edges = (corners[:, 1:] - corners[:, :1]).transpose(0, 2, 1)
    local = np.linalg.solve(edges[near], (points[:, None, :] - corners[near, 0])[..., None])[..., 0]
    return ((local >= -1e-9).all(axis=2) & (local.sum(axis=2) <= 1 + 1e-9)).any(axis=1)


def square_mesh() -> Mesh:
    """The unit square in two positively oriented triangles."""
    points = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    return Mesh(points, np.array([[0, 1, 2], [0, 2, 3]]), {"Label": np.array([3, 4], dtype=np.int32)})


# --- files ---------------------------------------------------------------------------------------------------------


def leftovers(folder: Path) -> list:
    """The names of the half-written files (``.partial``, bitemesh.io's atomic writes) left in ``folder``."""
    return [path.name for path in folder.iterdir() if ".partial" in path.name]


# --- the two-cavity shell as labelled contours -------------------------------------------------------------------

#: the two-cavity shell of bitemesh.core.shapes in mm: half an ellipsoid (z < 0) minus two half-ellipsoidal cavities
SCALE = 50.0
ELLIPSOIDS = {"EPI": ((0.0, 0.0, 0.0), (1.0, 0.9, 1.6)), "LV_ENDO": ((0.3, 0.0, 0.0), (0.4, 0.4, 1.2)),
              "RV_ENDO": ((-0.55, 0.0, 0.0), (0.22, 0.55, 1.0))}
SHELL_DOMAIN = "EPI - LV_ENDO - RV_ENDO"
#: the closed shell (sampled over its full height, no base plane): the outer ellipsoid minus both cavities, mm^3
SHELL_VOLUME = 4 / 3 * np.pi * SCALE**3 * sum(sign * np.prod(axes) for sign, (_, axes)
                                               in zip((1, -1, -1), ELLIPSOIDS.values()))


def ellipse_section(centre, axes, origin, u, v, spacing):
    """Points about ``spacing`` apart on the section of an ellipsoid by the plane origin + s u + t v, or None."""
    weight = 1.0 / np.asarray(axes) ** 2
    offset = origin - centre
    form = np.array([[np.sum(weight * u * u), np.sum(weight * u * v)],
                     [np.sum(weight * u * v), np.sum(weight * v * v)]])
    linear = np.array([np.sum(weight * offset * u), np.sum(weight * offset * v)])
    middle = -np.linalg.solve(form, linear)
    level = 1.0 - np.sum(weight * offset * offset) + linear @ np.linalg.solve(form, linear)
    if level <= 0:
        return None
    values, vectors = np.linalg.eigh(form)
    radii = np.sqrt(level / values)
    count = max(8, int(2 * np.pi * np.sqrt(0.5 * np.sum(radii ** 2)) / spacing))
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    st = middle + np.stack([radii[0] * np.cos(angle), radii[1] * np.sin(angle)], axis=1) @ vectors.T
    return origin + st[:, :1] * u + st[:, 1:] * v


def sample_shell(spacing=3.0, sax=tuple(range(-75, 0, 10)), lax_degrees=(0, 60, 120), tilt_degrees=5.0):
    """The shell's three ellipsoids cut by tilted short-axis planes 10 mm apart and long-axis planes at three angles.

    Returns points (n, 3), labels (n,) and slice ids (n,).
    """
    tilt = np.radians(tilt_degrees)
    planes = [(np.array([0.0, 0.0, float(z)]), np.array([np.cos(tilt), 0.0, -np.sin(tilt)]), np.array([0.0, 1.0, 0.0]))
              for z in sax]
    planes += [(np.zeros(3), np.array([np.cos(a), np.sin(a), 0.0]), np.array([0.0, 0.0, 1.0]))
               for a in np.radians(lax_degrees)]
    points, labels, slices = [], [], []
    for number, (origin, u, v) in enumerate(planes):
        for name, (centre, axes) in ELLIPSOIDS.items():
            section = ellipse_section(np.array(centre) * SCALE, np.array(axes) * SCALE, origin, u, v, spacing)
            if section is not None:
                points.append(section)
                labels += [name] * len(section)
                slices += [number] * len(section)
    return np.vstack(points), np.array(labels), np.array(slices)


def closed_shell_contours():
    """The whole shell's contours, short-axis slices over its full height 5 mm apart along each contour: a closed
    shell with two closed cavities (mesh it with base_plane "none"; its volume is SHELL_VOLUME)."""
    return sample_shell(spacing=5.0, sax=tuple(range(-75, 80, 10)))


# --- VTK forms (VTK is imported when they are called) -------------------------------------------------------------


def polydata(points, normals=None, **arrays):
    """Scattered points as vtkPolyData, with a ``Normals`` point array and any other named point arrays."""
    from bitemesh.convert import vtk_points
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkPolyData

    result = vtkPolyData()
    result.SetPoints(vtk_points(points))
    for name, values in {**({"Normals": normals} if normals is not None else {}), **arrays}.items():
        values = np.asarray(values, dtype=np.float64)
        if values.ndim == 2 and values.shape[1] == 2:
            values = np.column_stack([values, np.zeros(len(values))])
        array = numpy_to_vtk(np.ascontiguousarray(values), deep=True)
        array.SetName(name)
        result.GetPointData().AddArray(array)
    return result


def labelled_polydata(points, labels, slices=None):
    """Points with a string ``Label`` array and an integer ``Slice`` array, as a VTP of contours would hold."""
    from bitemesh.convert import vtk_points
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkStringArray
    from vtkmodules.vtkCommonDataModel import vtkPolyData

    result = vtkPolyData()
    result.SetPoints(vtk_points(points))
    names = vtkStringArray()
    names.SetName("Label")
    for label in labels:
        names.InsertNextValue(str(label))
    result.GetPointData().AddArray(names)
    if slices is not None:
        ids = numpy_to_vtk(np.asarray(slices, dtype=np.int32), deep=True)
        ids.SetName("Slice")
        result.GetPointData().AddArray(ids)
    return result


def vtk_sphere(radius=1.0, resolution=(16, 16), centre=(0.0, 0.0, 0.0), *, normals=True, reverse=False,
               hemisphere=False):
    """vtkSphereSource's triangulated sphere as vtkPolyData (``resolution``: theta, phi), outward wound with point
    normals; ``normals=False`` drops them, ``reverse`` winds it (and turns its normals) inward, ``hemisphere`` keeps
    the open cap z >= 0."""
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    source = vtkSphereSource()
    source.SetCenter(*map(float, centre))
    source.SetThetaResolution(resolution[0])
    source.SetPhiResolution(resolution[1])
    source.SetRadius(radius)
    if hemisphere:
        source.SetEndPhi(90.0)
    source.Update()
    surface = source.GetOutput()
    if reverse:
        from vtkmodules.vtkFiltersCore import vtkReverseSense

        flip = vtkReverseSense()
        flip.SetInputData(surface)
        flip.ReverseCellsOn()
        flip.ReverseNormalsOn()
        flip.Update()
        surface = flip.GetOutput()
    if not normals:
        surface.GetPointData().SetNormals(None)
        assert surface.GetPointData().GetNumberOfArrays() == 0
    return surface


def ball_label_map():
    """A voxelised ball (label 3) and a small box (label 7) in a vtkImageData with unequal spacing and dimensions
    and a non-zero origin.  Returns the image and the ball's centre, radius and voxel volume."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    spacing, origin, offset, radius = np.array([0.15, 0.18, 0.165]), np.array([10.0, -5.0, 3.0]), \
        np.array([6.5, 7.0, 7.2]), 5.5
    dims = tuple(int(n) for n in np.ceil((offset + radius + 1) / spacing) + 1)  # (88, 76, 85)
    centre = origin + offset
    index = np.stack(np.meshgrid(*(np.arange(n) for n in dims), indexing="ij"), axis=-1)
    xyz = origin + index * spacing
    labels = np.zeros(dims, dtype=np.uint8)
    ball = np.linalg.norm(xyz - centre, axis=-1) < radius
    labels[ball] = 3
    labels[-5:-1, 1:4, -5:-1] = 7  # another label, away from the ball: Label = 3 leaves it out
    image = vtkImageData()
    image.SetDimensions(*dims)
    image.SetSpacing(*spacing)
    image.SetOrigin(*origin)
    scalars = numpy_to_vtk(labels.ravel(order="F"), deep=True)  # VTK's point order: x fastest
    scalars.SetName("labels")
    image.GetPointData().SetScalars(scalars)
    return image, centre, radius, ball.sum() * np.prod(spacing)


def chain(source, *, cells=1500, radius=None, grid_spacing=None, method="mpu", margin=None, seed=0) -> SimpleNamespace:
    """The five VTK filters connected as the paper's pipeline on ``source`` (nothing runs yet)."""
    from bitemesh.algorithms import BitingSampler, DelaunayTetra, PointsToImplicit, QualityFilter, SpuriousCellFilter

    implicit = PointsToImplicit()
    implicit.SetInputData(source)
    implicit.SetMethod(method)
    implicit.SetGridSpacing(grid_spacing)
    implicit.SetMargin(margin)
    implicit.SetCells(cells)   # the grid I is laid out for R; BitingSampler takes that R from the image
    implicit.SetRadius(radius)
    biting = BitingSampler()
    biting.SetInputConnection(implicit.GetOutputPort())
    biting.SetSeed(seed)
    tetra = DelaunayTetra()
    tetra.SetInputConnection(biting.GetOutputPort())
    spurious = SpuriousCellFilter()
    spurious.SetInputConnection(0, tetra.GetOutputPort())
    spurious.SetInputConnection(1, implicit.GetOutputPort())
    quality = QualityFilter()
    quality.SetInputConnection(spurious.GetOutputPort())
    return SimpleNamespace(implicit=implicit, biting=biting, tetra=tetra, spurious=spurious, quality=quality,
                           filters=(implicit, biting, tetra, spurious, quality), source=source)


def output(algorithm, port=0):
    """What a filter of the chain holds on ``port`` (without updating it)."""
    return algorithm.GetOutputDataObject(port)


def field_value(dataset, name):
    """The first value of the field data array ``name``."""
    return dataset.GetFieldData().GetArray(name).GetValue(0)
