"""Reading points and contours, reading and writing meshes: one module per kind of file.

- :mod:`.tables`: text tables of points (columns by header names or by count, decimal commas);
- :mod:`.pointsets`: points and normals from tables and VTK-readable files (a volume mesh gives its boundary);
- :mod:`.contours`: labelled contour points (biv-me GPFiles, labelled tables and VTK files) and their config;
- :mod:`.meshes`: tetrahedral meshes through meshio;
- :mod:`.files`: what they share, the atomic write among it.

Label maps are read by :mod:`bitemesh.labelmap` (SimpleITK).  VTK and meshio are imported only when a file needs
them.
"""
from .contours import (LABELLED_EXTENSIONS, LABELLED_CONFIG_KEYS, looks_labelled, read_labelled_config,  # noqa: F401
                       read_labelled_points)
from .files import atomic_output  # noqa: F401
from .meshes import MESH_EXTENSIONS, MESHIO_FORMATS, REGION_ARRAYS, read_mesh, write_mesh  # noqa: F401
from .pointsets import POINT_EXTENSIONS, TEXT_POINT_EXTENSIONS, VTK_POINT_EXTENSIONS, read_points  # noqa: F401
