"""Removal of the Delaunay cells that lie outside the domain: the circumcentre test of Schaerer et al."""
from __future__ import annotations

import numpy as np

from .errors import check_number
from .grid import ImplicitGrid
from .mesh import circumspheres


def outside_cells(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, threshold: float = 0.4) -> np.ndarray:
    """(m,) bool, True for a cell whose circumcentre c is outside (f(c) < 0) and far from the surface.

    The distance from c to the surface is approximated by d(c) = |f(c)| / |grad f(c)|; a cell is outside when
    d(c) / R_circ > ``threshold``.  The paper's text says "inferior to", but measured on a shell and a torus that
    reading keeps the spurious cells (+26 % and +37 % volume); the ">" reading used here is the one that works.

    A cell whose centroid is outside (f < 0) is outside too: near a concave part of the surface the circumcentre
    test alone keeps cells that bridge the concavity (measured: +1.3 % volume on the two-cavity shell).
    """
    check_number(threshold, "threshold", low=0, high=1)
    centres, radii = circumspheres(points, cells)
    finite = np.isfinite(radii)
    outside = ~finite
    value = grid.evaluate(centres[finite])
    slope = np.maximum(np.linalg.norm(grid.gradient(centres[finite]), axis=1), 1e-12)
    outside[finite] = (value < 0) & (np.abs(value) / slope > threshold * radii[finite])
    return outside | (grid.evaluate(points[cells].mean(axis=1)) < 0)
