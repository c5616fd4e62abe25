"""Delaunay triangulation of the nodes with qhull, every simplex positively oriented."""
from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError

from ..errors import InvalidInputError, check_points
from ..mesh.simplicial import MAX_DIMENSION, signed_measures

#: qhull's options beyond 3-D: the biting's nodes, a jittered lattice, are nearly cospherical in many places, and
#: qhull's exact handling of that ('Qz', scipy's default) took 45 s on 11,000 nodes of a 4-ball where joggling the
#: input ('QJ': deterministic) takes 3.4 s, with the same 233,950 cells.
JOGGLED = "QJ Qbb Qc"


def delaunay(nodes: np.ndarray) -> np.ndarray:
    """Triangulate (n, k) nodes (k = 2 to :data:`MAX_DIMENSION`) with qhull, centred first so that coordinates far
    from the origin keep their precision.

    Returns
    -------
    cells : (m, k + 1) int64, triangles, tetrahedra, ... with positive signed measure (qhull's flat simplices
        dropped)
    """
    nodes = check_points(nodes, "nodes", dims=range(2, MAX_DIMENSION + 1))
    if len(nodes) < nodes.shape[1] + 1:
        raise InvalidInputError(f"nodes must hold at least {nodes.shape[1] + 1} points, got {len(nodes)}")
    centred = nodes - 0.5 * (nodes.min(axis=0) + nodes.max(axis=0))   # qhull's tolerances are absolute
    try:
        cells = Delaunay(centred, qhull_options=JOGGLED if nodes.shape[1] > 3 else None).simplices.astype(np.int64)
    except QhullError as error:
        raise InvalidInputError(f"nodes are degenerate (all on a line or a plane?): qhull says "
                                f"{str(error).splitlines()[0]}") from None
    measure = signed_measures(centred, cells)
    flipped = measure < 0
    cells[flipped, :2] = cells[flipped, 1::-1]
    return cells[measure != 0]
