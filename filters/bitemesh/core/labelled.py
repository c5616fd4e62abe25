"""Labelled contours to a mesh, the names users import: the work is in the package :mod:`bitemesh.core.contours`
(the slices and normals, one RBF per surface, the CSG, the base plane, the biv-me conventions, the domain's f, its
fit, and the source on the meshing spine)."""
from __future__ import annotations

from .contours.base import fit_base_plane  # noqa: F401
from .contours.cardiac import (BIVME_APEX, BIVME_DEFAULT_DOMAIN, BIVME_LABELS, BIVME_OUTLETS,  # noqa: F401
                               BIVME_SURFACES, BIVME_VALVES, CARDIAC_RADIUS, LV_DOMAIN, RV_WALL)
from .contours.fit import labelled_implicit  # noqa: F401
from .contours.function import LabelledImplicit, boundary_surfaces  # noqa: F401
from .contours.run import (LabelledMeshingResult, labelled_source, mesh_from_labelled_points,  # noqa: F401
                           run_labelled, thinnest_wall)
from .contours.surface_fit import KERNELS, fit_contour_rbf  # noqa: F401
