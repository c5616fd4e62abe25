"""The relaxation beyond 3-D: ODT moves of the nodes, then a new Delaunay triangulation carved as the first was.

The MeshOptimizer (:mod:`bitemesh.core.optimize.optimizer`) updates the cells by flips written for triangles and
tetrahedra.  In 4-D and 5-D the nodes move the same way (:func:`~bitemesh.core.optimize.relax.odt_targets`: interior
nodes to the volume-weighted mean of their cells' circumcentres, boundary nodes along f = 0) and the cells come
from qhull and the spine's own carve (:func:`~bitemesh.core.steps.repair.carve_domain`), which is the ODT of Alliez
et al. 2005 as first written: move, triangulate, repeat.  Measured (benchmarks/dimensions.md): the 4-ball at
100,000 cells, mean radius ratio 0.690 -> 0.781, cells below 0.1 0.48 -> 0.13 %, 8 -> 41 s; the 5-ball 0.589 ->
0.680; the cine's space-time heart (benchmarks/spacetime.md) 0.632 -> 0.648 for 1.5 times the time.
"""
from __future__ import annotations

import logging

from ..errors import MeshingError
from ..grid.sampled import ImplicitGrid
from ..mesh.quality import radius_ratio
from ..mesh.simplicial import Mesh
from ..mesh.validity import count_boundary_components
from ..optimize.measures import mean_edge_length
from ..optimize.relax import INTERIOR_MARGIN, MEAN_GAIN, odt_targets
from ..parameters import OptimizeParameters, SpuriousParameters
from ..progress import ProgressCallback, report, sub_progress
from .delaunay import delaunay
from .repair import carve_domain

logger = logging.getLogger("bitemesh")


def relax_by_triangulation(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters,
                           spurious: SpuriousParameters = SpuriousParameters(),
                           progress: ProgressCallback = None) -> Mesh:
    """Move the nodes of the valid ``mesh`` to their ODT targets, triangulate and carve them again; repeat.

    Stops after ``parameters.iterations`` moves, as soon as one raises the mean radius ratio by less than
    ``MEAN_GAIN`` (each is a whole triangulation and carve: on a space-time heart, whose walls are about R thick and
    whose nodes are nearly all on the boundary, the third gained nothing and each cost as much as the first carve),
    or when a new triangulation cannot be carved into a valid domain with as many boundary components.  Returns the
    valid mesh of the best mean radius ratio met (``mesh`` itself when none did better).
    """
    best, parts = mesh, count_boundary_components(mesh)
    history = [float(radius_ratio(mesh.points, mesh.cells).mean())]
    for iteration in range(parameters.iterations):
        targets = odt_targets(grid, mesh.points, mesh.cells, INTERIOR_MARGIN * mean_edge_length(mesh.points,
                                                                                               mesh.cells))
        try:
            mesh = carve_domain(grid, targets, delaunay(targets), spurious,
                                progress=sub_progress(progress, iteration / parameters.iterations,
                                                      (iteration + 1) / parameters.iterations))
        except MeshingError as error:
            logger.info("relaxation stopped: the moved nodes gave no valid domain (%s)", error)
            break
        if count_boundary_components(mesh) != parts:
            logger.info("relaxation stopped: the moved nodes changed the boundary's parts")
            break
        history.append(float(radius_ratio(mesh.points, mesh.cells).mean()))
        if history[-1] > max(history[:-1]):
            best = mesh
        report(progress, (iteration + 1) / parameters.iterations,
               f"relaxation {iteration + 1}: mean radius ratio {history[-1]:.4f}")
        if history[-1] < max(history[:-1]) + MEAN_GAIN:
            break
    return best
