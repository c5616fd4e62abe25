"""numpy <-> VTK for the data the filters exchange: point sets, the implicit image, simplicial meshes and their tags.

Only ``vtkmodules`` imports and API present in VTK 9.2, so that ParaView 5.11 loads the same code.
"""
from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIntArray, vtkPoints, vtkStringArray, vtkVersion
from vtkmodules.vtkCommonDataModel import (VTK_TETRA, VTK_TRIANGLE, vtkCellArray, vtkImageData, vtkPolyData,
                                           vtkUnstructuredGrid)

from .core.sources.contours.cardiac import time_frame
from .core.columns import role
from .core.errors import InvalidInputError
from .core.grid.sampled import ImplicitGrid
from .core.mesh.simplicial import Mesh

#: the point array of the implicit image: f > 0 inside.
IMPLICIT_ARRAY = "Implicit"


def point_coordinates(dataset) -> np.ndarray:
    """(n, 3) float64 copy of the points of a vtkPointSet (empty (0, 3) when it has none)."""
    points = dataset.GetPoints()
    if points is None or points.GetNumberOfPoints() == 0:
        return np.zeros((0, 3))
    return numpy_support.vtk_to_numpy(points.GetData()).astype(np.float64, copy=True).reshape(-1, 3)


def point_array(dataset, name: str):
    """A copy of the named point-data array as numpy, or None."""
    array = dataset.GetPointData().GetArray(name)
    return None if array is None else numpy_support.vtk_to_numpy(array).copy()


def named_point_array(dataset, kind: str):
    """The first one-component point-data array (numbers or strings) whose name means ``kind`` ("label" or
    "slice", see :mod:`bitemesh.core.columns`: a GPFile read as a table gives "contour type" and "frameID"), as a
    numpy copy; None when there is none."""
    data = dataset.GetPointData()
    for index in range(data.GetNumberOfArrays()):
        array = data.GetAbstractArray(index)
        if role(array.GetName() or "") != kind or array.GetNumberOfComponents() != 1:
            continue
        if array.IsA("vtkStringArray"):
            return np.array([array.GetValue(i) for i in range(array.GetNumberOfTuples())], dtype=str)
        return np.array(numpy_support.vtk_to_numpy(array)).reshape(-1)
    return None


def point_labels(dataset, what: str = "the input"):
    """The contour labels of a point set and their slices: ((n,) labels or None, (n,) int64 slice ids or None).

    Labels come from a point array ``Label`` (integers or strings), slices from ``Slice`` or ``FrameID``.
    Raises InvalidInputError (naming ``what``) for labels that are non-integer numbers, slices that are not
    integers, or a time-frame array ("time frame") of several frames on one slice.
    """
    labels = named_point_array(dataset, "label")
    if labels is not None and labels.dtype.kind == "f" and not (np.isfinite(labels).all()
                                                                and np.all(labels == np.round(labels))):
        raise InvalidInputError(f"{what}: the Label array holds non-integer numbers; labels are integers or strings")
    slices = named_point_array(dataset, "slice") if labels is not None else None
    if slices is not None:
        if slices.dtype.kind not in "iuf" or not np.all(np.isfinite(slices.astype(float))) \
                or np.any(slices.astype(float) != np.round(slices.astype(float))):
            raise InvalidInputError(f"{what}: the slice array (Slice or FrameID) must hold integers")
        slices = slices.astype(np.int64)
    if labels is not None:
        frames = named_point_array(dataset, "frame")
        if frames is not None and frames.dtype.kind in "iuf":
            time_frame(frames.astype(float), slices, None, what,
                       "a Threshold on the time-frame array (ParaView) or read_labelled_points(frame=...)")
    return labels, slices


def dataset_samples(dataset):
    """What a vtkPointSet holds as samples: (points, normals or None, labels or None, slices or None).

    With a ``Label`` point array (labelled contours): (n, 3) points, (n,) labels and slice ids (:func:`point_labels`)
    and no normals.  Else scattered points: the ``Normals`` point array or the normals attribute; points with z = 0
    everywhere are 2D (a contour in the xy plane), and both come back with two columns.
    """
    from vtkmodules.vtkCommonDataModel import vtkPointSet
    if not isinstance(dataset, vtkPointSet) or dataset.GetNumberOfPoints() == 0:
        raise InvalidInputError("the input holds no points; connect scattered points (vtkPolyData) or a label map")
    labels, slices = point_labels(dataset)
    if labels is not None:
        return point_coordinates(dataset), None, labels, slices
    normals = dataset.GetPointData().GetNormals()
    normals = point_array(dataset, "Normals") if normals is None else numpy_support.vtk_to_numpy(normals).copy()
    points = planar_as_2d(point_coordinates(dataset))
    if normals is not None and normals.ndim == 2 and normals.shape[1] > points.shape[1]:
        normals = normals[:, :points.shape[1]]
    return points, normals, None, None


def image_voxels(image: vtkImageData):
    """A label map as VTK holds it: ((n_i, n_j[, n_k]) labels indexed [i, j, k], (k + 1, k + 1) index -> physical
    matrix of its spacing and origin); a 2D image (one slice) gives 2D."""
    dims = image.GetDimensions()
    dim = 2 if dims[2] == 1 else 3
    scalars = image.GetPointData().GetScalars()
    if scalars is None:
        raise InvalidInputError("the label map has no point scalars (the labels)")
    labels = numpy_support.vtk_to_numpy(scalars).reshape(dims, order="F").reshape(dims[:dim])
    matrix = np.eye(dim + 1)
    matrix[:dim, :dim] = np.diag(image.GetSpacing()[:dim])
    matrix[:dim, dim] = image.GetOrigin()[:dim]
    return labels, matrix


def planar_as_2d(points: np.ndarray) -> np.ndarray:
    """(n, 2) when every z is 0 (a 2D point set, as VTK stores it), else the (n, 3) points unchanged."""
    return points[:, :2] if len(points) and np.all(points[:, 2] == 0) else points


def _as_3d(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    return np.column_stack([points, np.zeros(len(points))]) if points.shape[1] == 2 else points


def vtk_points(coordinates: np.ndarray) -> vtkPoints:
    """vtkPoints holding (n, 2) or (n, 3) coordinates (2D gets z = 0)."""
    points = vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(_as_3d(coordinates)), deep=True))
    return points


def field_array(name: str, values, integer: bool = False):
    """A named one-component VTK array of ``values``."""
    array = (vtkIntArray if integer else vtkDoubleArray)()
    array.SetName(name)
    for value in values:
        array.InsertNextValue(value)
    return array


def nodes_to_polydata(nodes: np.ndarray) -> vtkPolyData:
    """A vtkPolyData of (n, k) nodes, one vertex cell each (so that they render)."""
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points(nodes))
    polydata.SetVerts(cell_array(np.arange(len(nodes), dtype=np.int64)[:, None]))
    return polydata


def cell_array(cells: np.ndarray) -> vtkCellArray:
    """vtkCellArray of (m, j) int64 connectivity (the offsets/connectivity layout of VTK 9)."""
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    offsets = np.arange(0, cells.size + 1, cells.shape[1], dtype=np.int64)
    array = vtkCellArray()
    array.SetData(numpy_support.numpy_to_vtkIdTypeArray(offsets, deep=True),
                  numpy_support.numpy_to_vtkIdTypeArray(cells.ravel(), deep=True))
    return array


def grid_to_image(grid: ImplicitGrid, image: vtkImageData | None = None) -> vtkImageData:
    """The implicit grid as a vtkImageData with point scalars ``Implicit`` (2D grids get one slice in z)."""
    image = vtkImageData() if image is None else image
    dims = list(grid.shape) + [1] * (3 - grid.dim)
    image.SetExtent(0, dims[0] - 1, 0, dims[1] - 1, 0, dims[2] - 1)
    image.SetOrigin(*(list(grid.origin) + [0.0] * (3 - grid.dim)))
    image.SetSpacing(*(list(grid.spacing) + [1.0] * (3 - grid.dim)))
    values = numpy_support.numpy_to_vtk(np.ascontiguousarray(grid.values.ravel(order="F")), deep=True)
    values.SetName(IMPLICIT_ARRAY)
    image.GetPointData().SetScalars(values)
    return image


def image_to_grid(image: vtkImageData, name: str = IMPLICIT_ARRAY) -> ImplicitGrid:
    """The ``Implicit`` point array of a vtkImageData as an ImplicitGrid (a one-slice image gives a 2D grid)."""
    array = image.GetPointData().GetArray(name) if image is not None else None
    if array is None or image.GetNumberOfPoints() == 0:
        raise InvalidInputError(f"the implicit image is empty or has no point array '{name}'; "
                                "connect the output of PointsToImplicit")
    dims = image.GetDimensions()
    dim = 2 if dims[2] == 1 else 3
    values = numpy_support.vtk_to_numpy(array).astype(np.float64).reshape(dims, order="F")
    return ImplicitGrid(origin=np.array(image.GetOrigin()[:dim]), spacing=np.array(image.GetSpacing()[:dim]),
                        values=values.reshape(dims[:dim]) if dim == 2 else values)


def mesh_to_unstructured(mesh: Mesh, grid: vtkUnstructuredGrid | None = None) -> vtkUnstructuredGrid:
    """A vtkUnstructuredGrid of VTK_TETRA (VTK_TRIANGLE in 2D) cells with the mesh's cell data (the regions as the
    int32 cell array ``Region``) and point data and, when the mesh has them, its tag names as field data
    (:func:`add_tag_names`)."""
    grid = vtkUnstructuredGrid() if grid is None else grid
    grid.SetPoints(vtk_points(mesh.points))
    cell_type = VTK_TETRA if mesh.cells.shape[1] == 4 else VTK_TRIANGLE
    grid.SetCells(cell_type, cell_array(mesh.cells))
    for attributes, arrays in ((grid.GetCellData(), mesh.cell_data), (grid.GetPointData(), mesh.point_data)):
        for name, values in arrays.items():
            array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
            array.SetName(name)
            attributes.AddArray(array)
    if mesh.tag_names:
        add_tag_names(grid, mesh.tag_names)
    return grid


def cell_types(grid: vtkUnstructuredGrid) -> np.ndarray:
    """(m,) VTK cell type of each cell (GetCellTypesArray up to VTK 9.5, GetCellTypes from 9.6)."""
    modern = vtkVersion.GetVTKMajorVersion() * 100 + vtkVersion.GetVTKMinorVersion() >= 906
    array = grid.GetCellTypes() if modern else grid.GetCellTypesArray()
    return numpy_support.vtk_to_numpy(array) if array is not None else \
        np.array([grid.GetCellType(i) for i in range(grid.GetNumberOfCells())], dtype=np.uint8)


def unstructured_to_mesh(grid: vtkUnstructuredGrid) -> Mesh:
    """The tetrahedra (or, without any, the triangles) of a vtkUnstructuredGrid, with their cell and point data (the
    numeric arrays), as a Mesh.

    A triangle mesh whose points all have z = 0 is 2D.
    """
    if grid is None or grid.GetNumberOfCells() == 0:
        raise InvalidInputError("the mesh is empty: it has no cells; connect a DelaunayTetra or SpuriousCellFilter")
    points = point_coordinates(grid)
    types = cell_types(grid)
    cells = grid.GetCells()
    offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    connectivity = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    found = [(np.flatnonzero(types == cell_type), size) for cell_type, size in ((VTK_TETRA, 4), (VTK_TRIANGLE, 3))]
    chosen, size = next(((members, size) for members, size in found if members.size), (None, 0))
    if chosen is None:
        raise InvalidInputError(f"the mesh has no tetrahedra or triangles (cell types found: {sorted(set(types))})")
    table = connectivity[offsets[chosen][:, None] + np.arange(size)]
    if size == 3 and np.all(points[:, 2] == 0):
        points = points[:, :2]
    data, point_data = {}, {}
    for attributes, found, rows in ((grid.GetCellData(), data, chosen), (grid.GetPointData(), point_data, None)):
        for index in range(attributes.GetNumberOfArrays()):
            array = attributes.GetArray(index)
            if array is not None and array.GetName():
                values = numpy_support.vtk_to_numpy(array)
                found[array.GetName()] = (values if rows is None else values[rows]).copy()
    return Mesh(points, table, data, point_data=point_data)


#: field-data arrays on the implicit image that carry the data's surface samples to the SpuriousCellFilter, which
#: checks the mesh's fidelity against them, (n, 3) (their noise and gap are in the plan); and the point array
#: :data:`UNSAMPLED_ARRAY`.
SAMPLE_ARRAYS = ("Samples",)
#: the field-data array that carries the spine's plan down the VTK chain: one tuple, a named component each: R
#: (user units), 1 for a myocardium (its handles removed), the samples' noise and gap (user units), 1 for one fit
#: of scattered points (Source.one_fit); NaN: not set.
PLAN_ARRAY = "BitemeshPlan"
PLAN = ("Radius", "Myocardium", "SampleNoise", "SampleGap", "OneFit")
#: a point array of the implicit image, 1 where the boundary near a node is made by the method rather than the
#: data (a heart's base, a derived surface), left out of the fidelity's boundary-to-samples measure.
UNSAMPLED_ARRAY = "Unsampled"
#: a point array of the implicit image: which of the data's surfaces gives f near each node (-1: none, the base),
#: so that the handle repair cuts no wall from one surface to another (labelled contours).
SURFACE_ARRAY = "DataSurface"


def attach_surfaces(image, surfaces) -> None:
    """Put which of the data's surfaces gives f at each node (an ImplicitGrid of ``image``'s layout, -1 for none)
    on ``image`` as a point array (:data:`SURFACE_ARRAY`), for the handle repair; nothing for None."""
    if surfaces is not None:
        array = numpy_support.numpy_to_vtk(np.ascontiguousarray(surfaces.values.ravel(order="F")), deep=True)
        array.SetName(SURFACE_ARRAY)
        image.GetPointData().AddArray(array)


def attached_surfaces(image):
    """callable (m, k) points -> (m,) int, the surface :func:`attach_surfaces` put at the node nearest each point, or
    None when ``image`` carries none."""
    if image is None or not image.GetPointData().GetArray(SURFACE_ARRAY):
        return None
    grid = image_to_grid(image, SURFACE_ARRAY)
    return lambda points: grid.values[grid.nearest_nodes(points)].astype(np.int64)


def attach_samples(image, samples: np.ndarray, noise: float, gap: float, unsampled=None) -> None:
    """Put the data's surface samples (n, k) on ``image``'s field data (see :data:`SAMPLE_ARRAYS`) and, when given,
    the ``unsampled`` mask of its nodes (an ImplicitGrid of the image's layout, 1 or 0) as a point array."""
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(_as_3d(samples)), deep=True)
    array.SetName("Samples")
    image.GetFieldData().AddArray(array)
    attach_plan(image, SampleNoise=noise, SampleGap=gap)
    if unsampled is not None:
        mask = numpy_support.numpy_to_vtk(np.ascontiguousarray(unsampled.values.ravel(order="F")), deep=True)
        mask.SetName(UNSAMPLED_ARRAY)
        image.GetPointData().AddArray(mask)


def attached_samples(image, dim: int):
    """(samples (n, dim), noise, gap, the unsampled mask as an ImplicitGrid or None) from ``image``'s field and
    point data, or None when it carries no samples."""
    data = image.GetFieldData() if image is not None else None
    array = data.GetArray("Samples") if data is not None else None
    if array is None:
        return None
    samples = numpy_support.vtk_to_numpy(array).astype(np.float64).reshape(-1, 3)[:, :dim]
    plan = plan_of(image)
    unsampled = image_to_grid(image, UNSAMPLED_ARRAY) if image.GetPointData().GetArray(UNSAMPLED_ARRAY) else None
    return samples, plan.get("SampleNoise", 0.0), plan.get("SampleGap", 0.0), unsampled


def attach_plan(dataset, **values) -> None:
    """Set ``values`` (names of :data:`PLAN`, numbers) in ``dataset``'s plan, keeping the rest of what it holds."""
    plan = {**plan_of(dataset), **values}
    array = vtkDoubleArray()
    array.SetName(PLAN_ARRAY)
    array.SetNumberOfComponents(len(PLAN))
    for index, name in enumerate(PLAN):
        array.SetComponentName(index, name)
    array.InsertNextTuple([float(plan.get(name, np.nan)) for name in PLAN])
    dataset.GetFieldData().AddArray(array)   # replaces the plan of that name


def plan_of(dataset) -> dict:
    """The plan a dataset carries (:data:`PLAN_ARRAY`): name -> number, for those set; {} without one."""
    array = dataset.GetFieldData().GetArray(PLAN_ARRAY) if dataset is not None else None
    if array is None or array.GetNumberOfTuples() == 0:
        return {}
    return {name: value for name, value in zip(PLAN, array.GetTuple(0)) if not np.isnan(value)}


def add_field_values(dataset, values: dict, prefix: str = "") -> None:
    """One one-value field-data array per number of ``values`` (name -> number), named ``prefix`` + CamelCase."""
    for name, value in values.items():
        camel = "".join(part.capitalize() for part in name.split("_"))
        dataset.GetFieldData().AddArray(field_array(prefix + camel, [float(value)]))


# --- tags: the meshing filters' second output -----------------------------------------------------------------------

#: the cell array of the tagged facets' vtkPolyData: each facet's tag (int32 > 0).
SURFACE_TAG_ARRAY = "SurfaceTag"
#: the cell array of the regions on the mesh's vtkUnstructuredGrid (int32 > 0).
REGION_ARRAY = "Region"
#: the field-data arrays naming the tags, parallel, one entry a name: ``TagNames`` (vtkStringArray), ``TagValues``
#: and ``TagDimensions`` (vtkIntArray): dimension k (3, 2 in 2D) for a region, k - 1 for a facet tag.
TAG_NAME_ARRAYS = ("TagNames", "TagValues", "TagDimensions")


def add_tag_names(dataset, tag_names: dict) -> None:
    """Put ``tag_names`` (name -> (tag, dimension)) on ``dataset``'s field data as :data:`TAG_NAME_ARRAYS`."""
    names = vtkStringArray()
    names.SetName(TAG_NAME_ARRAYS[0])
    for name in tag_names:
        names.InsertNextValue(name)
    data = dataset.GetFieldData()
    data.AddArray(names)
    for column, array_name in enumerate(TAG_NAME_ARRAYS[1:]):
        data.AddArray(field_array(array_name, [int(value[column]) for value in tag_names.values()], integer=True))


def tag_names_of(dataset) -> dict:
    """name -> (tag, dimension) from ``dataset``'s field data (:data:`TAG_NAME_ARRAYS`); {} without them.

    Raises InvalidInputError when they are there but not parallel (or not a string and two integer arrays)."""
    data = dataset.GetFieldData()
    arrays = [data.GetAbstractArray(name) for name in TAG_NAME_ARRAYS]
    if all(array is None for array in arrays):
        return {}
    counts = [None if array is None else array.GetNumberOfValues() for array in arrays]
    kinds = [array is not None and array.IsA(kind) for array, kind in zip(arrays, ("vtkStringArray", "vtkDataArray",
                                                                                    "vtkDataArray"))]
    if not all(kinds) or len(set(counts)) != 1:
        raise InvalidInputError(f"the field data {', '.join(TAG_NAME_ARRAYS)} must be a vtkStringArray and two "
                                f"integer arrays of the same length, got {dict(zip(TAG_NAME_ARRAYS, counts))}; "
                                "make them with bitemesh.convert.add_tag_names")
    names, values, dimensions = arrays
    return {names.GetValue(i): (int(values.GetTuple1(i)), int(dimensions.GetTuple1(i))) for i in range(counts[0])}


def tags_to_polydata(mesh: Mesh, polydata: vtkPolyData | None = None) -> vtkPolyData:
    """The tagged facets of a mesh as a vtkPolyData that shares every point of the mesh (point id = node id):
    triangles (lines in 2D) with the int32 cell array ``SurfaceTag``, and the names of every tag, regions
    included, as field data (:func:`add_tag_names`).  A mesh without tags gives the points and no cells."""
    polydata = vtkPolyData() if polydata is None else polydata
    polydata.SetPoints(vtk_points(mesh.points))
    facets = np.zeros((0, mesh.dim), np.int64) if mesh.facets is None else mesh.facets
    (polydata.SetPolys if mesh.dim == 3 else polydata.SetLines)(cell_array(facets))
    tags = numpy_support.numpy_to_vtk(np.ascontiguousarray(
        np.zeros(0, np.int32) if mesh.facet_tags is None else mesh.facet_tags, dtype=np.int32), deep=True)
    tags.SetName(SURFACE_TAG_ARRAY)
    polydata.GetCellData().AddArray(tags)
    polydata.GetCellData().SetActiveScalars(SURFACE_TAG_ARRAY)
    add_tag_names(polydata, mesh.tag_names)
    return polydata


def polydata_to_tags(polydata: vtkPolyData, mesh: Mesh):
    """The tags that :func:`tags_to_polydata` put on ``polydata``, checked against ``mesh`` (the mesh they tag).

    Returns
    -------
    facets : (b, k) int64 node ids of ``mesh``; facet_tags : (b,) int32; tag_names : name -> (tag, dimension)

    Raises InvalidInputError naming what is wrong (another mesh's points, facets that are not triangles (lines in
    2D), no ``SurfaceTag``), with the hint to connect the meshing filter's second output.
    """
    hint = "connect the tagged facets of this mesh (the meshing filter's second output, port 1)"
    count = 0 if polydata is None else polydata.GetNumberOfPoints()
    if count != len(mesh.points):
        raise InvalidInputError(f"the tagged facets hold {count} points and the mesh {len(mesh.points)}: they must "
                                f"share the mesh's points (point id = node id); {hint}")
    scale = float(np.ptp(mesh.points, axis=0).max()) if len(mesh.points) else 1.0
    if not np.allclose(point_coordinates(polydata)[:, :mesh.dim], mesh.points, rtol=0, atol=1e-9 * scale):
        raise InvalidInputError(f"the tagged facets' points are not the mesh's (point id = node id); {hint}")
    cells = polydata.GetPolys() if mesh.dim == 3 else polydata.GetLines()
    offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    if len(offsets) - 1 != polydata.GetNumberOfCells() or np.any(np.diff(offsets) != mesh.dim):
        kind = "triangles" if mesh.dim == 3 else "lines"
        raise InvalidInputError(f"the tagged facets of a {mesh.dim}D mesh must be {kind} and nothing else; {hint}")
    tags = polydata.GetCellData().GetArray(SURFACE_TAG_ARRAY)
    if tags is None or tags.GetNumberOfTuples() != len(offsets) - 1:
        raise InvalidInputError(f"the tagged facets have no cell array {SURFACE_TAG_ARRAY} (one tag a facet); {hint}")
    facets = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64).reshape(-1, mesh.dim)
    return facets, numpy_support.vtk_to_numpy(tags).astype(np.int32), tag_names_of(polydata)


def with_polydata_tags(mesh: Mesh, polydata: vtkPolyData) -> Mesh:
    """``mesh`` (e.g. from :func:`unstructured_to_mesh` of a meshing filter's port 0, with its ``Region``) with the
    tags of ``polydata`` (its port 1, :func:`polydata_to_tags`)."""
    return mesh.with_tags(*polydata_to_tags(polydata, mesh))
