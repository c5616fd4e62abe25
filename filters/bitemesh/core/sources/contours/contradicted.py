"""A contour the other slices contradict: its points that lie far from the surface the other slices give.

At end-systole the base has moved down through the basal short-axis slice, which now cuts the heart where its section
changes fastest; exports close such a contour across the outflow tract or the valve by a chord.  The long-axis
views, which see the base, cross that slice 9-22 mm from the contour while every other contour meets them within
1-1.4 mm (biv-me patient1, frames 6 and 13), and a surface through every point followed the chord: a block of
myocardium 15 mm thick across the LV outflow tract, the LV cavity 12 % under biv-me's.  biv-me's fit leaves the chord
10-18 mm away and follows the long-axis views.

The registration names such a contour (:attr:`~bitemesh.core.sources.contours.registration.Registration.contradicted`);
here its surface is fitted without that slice, and the contour's points farther than :data:`FAR` from that fit are
left out, with a note naming the slice, the surface and how many; the points the other slices agree with stay.  The
mesher and the template fit (:mod:`bitemesh.fitting`) leave out the same points.
"""
from __future__ import annotations

import numpy as np

from ...implicit.samples import slice_spacing
from .registration import FAR
from .slices import GAP_FACTOR, contour_normals, slice_planes
from .surface_fit import PATCH_PER_GAP, fit_contour_rbf


def without_contradicted(points, labels, slices, contradicted: dict, surfaces: dict, *,
                         gap_factor: float = GAP_FACTOR, scale: float = 1.0, **rbf):
    """(points, labels, slices) without the points of the ``contradicted`` contours that lie farther than
    :data:`FAR` from their surface fitted without their slice, and the notes that name them.

    Parameters
    ----------
    points : (n, 3) float64, input units; labels : (n,) str; slices : (n,) int slice ids (registered)
    contradicted : (slice id, surface name) -> how many crossings lie far from that contour
        (:class:`~bitemesh.core.sources.contours.registration.Registration`)
    surfaces : surface name -> its labels
    gap_factor : of :func:`~bitemesh.core.sources.contours.slices.contour_normals`
    scale : the input's mm per unit of ``points`` in the notes
    rbf : kernel, offset, smoothing of :func:`~bitemesh.core.sources.contours.surface_fit.fit_contour_rbf`
    """
    far = np.zeros(len(points), bool)
    notes = ()
    planes = slice_planes(points, slices) if contradicted else {}
    for name in sorted({surface for _, surface in contradicted}):
        members = np.flatnonzero(np.isin(labels, surfaces[name]))
        normals = contour_normals(points[members], slices[members], planes, gap_factor=gap_factor)
        for number in sorted(number for number, surface in contradicted if surface == name):
            mine = slices[members] == number
            others = members[~mine]
            if len(others) < 10:   # no surface without it
                continue
            function = fit_contour_rbf(points[others], normals[~mine], min_patch=PATCH_PER_GAP * slice_spacing(
                points[others], slices[others]), near=points[members[mine]], **rbf)
            distance = np.abs(function(points[members[mine]]))
            beyond = distance > FAR
            if beyond.any():
                far[members[mine][beyond]] = True
                notes += (f"slice {number}'s {name} contour: {int(beyond.sum())} of its {int(mine.sum())} points left "
                          f"out, {_span(scale * distance[beyond])} mm from the surface the other slices give "
                          f"({contradicted[number, name]} of their contours' crossings with that slice lie far from "
                          "it): a contour closed across a valve or the outflow tract, or moved through its plane by "
                          "its breath-hold",)
    return points[~far], labels[~far], slices[~far], notes


def _span(lengths) -> str:
    """'6-12', or '6' when the lengths round alike."""
    low, high = f"{lengths.min():.0f}", f"{lengths.max():.0f}"
    return low if low == high else f"{low}-{high}"
