"""Reading points and contours, reading and writing meshes: one module per kind of file.

- :mod:`.tables`: text tables of points (columns by header names or by count, decimal commas);
- :mod:`.pointsets`: points and normals from tables and VTK-readable files (a volume mesh gives its boundary);
- :mod:`.contours`: labelled contour points (biv-me GPFiles, labelled tables and VTK files) and their config;
- :mod:`.meshes` (writing) and :mod:`.mesh_reading`: tetrahedral meshes with their tags (meshio; :mod:`.xdmf` for
  dolfinx, :mod:`.abaqus`'s surfaces, :mod:`.opencarp`, :mod:`.folders` for cardiac-geometries and pulse);
- :mod:`.labelmaps`: label maps (NRRD, NIfTI, MetaImage) through SimpleITK, meshed by :mod:`bitemesh.labelmap`;
- :mod:`.files`: what they share, the atomic write among it.

VTK, meshio and SimpleITK are imported only when a file needs them.
"""
from .contours import (LABELLED_EXTENSIONS, LABELLED_CONFIG_KEYS, looks_labelled, read_labelled_config,  # noqa: F401
                       read_labelled_points)
from .files import atomic_output, remove_stale_partials, stale_partials  # noqa: F401
from .labelmaps import LABEL_MAP_EXTENSIONS, LabelMap, read_label_map  # noqa: F401
from .mesh_reading import read_mesh  # noqa: F401
from .meshes import (FACET_ARRAY, MESH_EXTENSIONS, MESHIO_FORMATS, NO_CELL_ARRAYS, REGION_ARRAYS,  # noqa: F401
                     check_holds, mesh_files, write_mesh, write_time_series)
from .pointsets import POINT_EXTENSIONS, TEXT_POINT_EXTENSIONS, VTK_POINT_EXTENSIONS, read_points  # noqa: F401

