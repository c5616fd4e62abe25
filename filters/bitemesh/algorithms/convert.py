"""Deprecated: numpy <-> VTK conversion moved to :mod:`bitemesh.convert` (below the readers and the filters).

``from bitemesh.algorithms.convert import mesh_to_unstructured`` (as the README once showed) still works and warns;
import from :mod:`bitemesh.convert` instead.
"""
import warnings

from ..convert import (IMPLICIT_ARRAY, SAMPLE_ARRAYS, add_field_values, attach_samples,  # noqa: F401
                       attached_samples, cell_array, cell_types, field_array, grid_to_image, image_to_grid,
                       mesh_to_unstructured, named_point_array, nodes_to_polydata, point_array, point_coordinates,
                       point_labels, unstructured_to_mesh, vtk_points)

__all__ = ["IMPLICIT_ARRAY", "SAMPLE_ARRAYS", "add_field_values", "attach_samples", "attached_samples", "cell_array",
           "cell_types", "field_array", "grid_to_image", "image_to_grid", "mesh_to_unstructured",
           "named_point_array", "nodes_to_polydata", "point_array", "point_coordinates", "point_labels",
           "unstructured_to_mesh", "vtk_points"]

warnings.warn("bitemesh.algorithms.convert is deprecated; import from bitemesh.convert", DeprecationWarning,
              stacklevel=2)
