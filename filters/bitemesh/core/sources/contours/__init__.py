"""Labelled contours as a source of f: sparse contours on slices (a cardiac MR study's short- and long-axis
slices), each point labelled with the surface it was drawn on, to the implicit function of a domain they bound.

- :mod:`.slices`: the slice planes (given or found) and each point's in-plane outward normal;
- :mod:`.surface_fit`: one implicit per surface, the partition-of-unity RBF of :mod:`bitemesh.core.implicit.rbf` through
  the contour points and their off-surface points;
- :mod:`.csg`: the domain's expression of surfaces (difference, union, intersection) and its evaluation;
- :mod:`.base_plane`: the plane that cuts the domain at the base (through the valves, or a user's);
- :mod:`.cardiac`: biv-me's labels and conventions, the surfaces derived when one is missing, the plausibility
  checks of a heart's mesh, the time frames of contour files;
- :mod:`.function`: :class:`~.function.LabelledImplicit`, the domain's f;
- :mod:`.fit`: :func:`~.fit.labelled_implicit`, every surface fitted and the domain built;
- :mod:`.run`: :func:`~.run.labelled_source` (the Source the spine meshes) and :func:`~.run.run_labelled`.

:mod:`bitemesh.core.labelled` re-exports the names users import.  Nothing is imported here, so that reading a
contour file (which needs :func:`.cardiac.time_frame`) does not load the spine.
"""
