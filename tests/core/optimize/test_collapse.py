"""Edge collapse of the cells flat against the surface (bitemesh.core.optimize.collapse): whatever it collapses, the
mesh stays a valid domain with the same topology, no cell gets worse than the worst it replaced, the volume changes by
no
more than the cells around the nodes removed, and only those cells change.  Then the issue-12 case it was made for:
the two-cavity shell at 136,000 cells, where the surface triangulation folded and 5 cells stayed below the bounds."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from bitemesh.core.optimize.collapse import collapse_flat_cells
from bitemesh.core.errors import BitemeshWarning
from bitemesh.core.mesh.simplicial import Mesh, signed_measures
from bitemesh.core.optimize.optimizer import topology
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid, radius_for_cells
from bitemesh.core.mesh.validity import check_valid_domain
from bitemesh.core.mesh.quality import dihedral_angles, radius_ratio, signed_radius_ratio
from bitemesh.core.shapes import annulus, die, torus, two_cavity_heart, two_cavity_shell
from bitemesh.core.optimize.slivers import poor_cells

from tests.builders import sampled


def plain_mesh(shape, cells, seed):
    """The paper's plain method on ``shape``: its flat boundary cells are what the collapse acts on."""
    radius = radius_for_cells(shape.measure, cells, shape.dim)
    grid = sampled(shape, radius / 4)
    plain = OptimizeParameters(optimize=0)
    return mesh_from_grid(grid, BitingParameters(radius=radius, seed=seed), optimize=plain).mesh


@pytest.mark.parametrize("shape, cells, seed", [(die(), 3000, 0), (torus(), 3000, 1), (two_cavity_shell(), 3000, 2),
                                                (two_cavity_heart(), 3000, 3), (annulus(), 800, 4)],
                         ids=["die", "torus", "two-cavity shell", "two-cavity heart", "annulus 2D"])
def test_a_collapse_keeps_a_valid_domain_of_the_same_topology_and_changes_only_the_cells_around_it(shape, cells,
                                                                                                   seed):
    mesh = plain_mesh(shape, cells, seed)
    poor = poor_cells(mesh.points, mesh.cells, 20.0, 0.3)
    points, collapsed = collapse_flat_cells(mesh.points, mesh.cells, poor)
    after = Mesh(points, collapsed)
    removed = np.setdiff1d(np.arange(len(mesh.points)), _kept_nodes(mesh.points, points))
    if shape.dim == 3:
        assert len(removed) > 0   # the plain method leaves flat boundary cells with a collapse that helps
    assert check_valid_domain(after) == []
    assert topology(after) == topology(mesh)
    assert np.array_equal(np.unique(collapsed), np.arange(len(points)))   # no node left unused
    assert signed_radius_ratio(points, collapsed).min() >= signed_radius_ratio(mesh.points, mesh.cells).min()
    star = np.isin(mesh.cells, removed).any(axis=1)   # the cells around the nodes removed
    volume = signed_measures(mesh.points, mesh.cells)
    assert abs(signed_measures(points, collapsed).sum() - volume.sum()) <= volume[star].sum() + 1e-12
    untouched = mesh.cells[~star] - np.searchsorted(removed, mesh.cells[~star])   # renumbered as the collapse does
    assert {tuple(row) for row in untouched.tolist()} <= {tuple(row) for row in collapsed.tolist()}


def _kept_nodes(before, after):
    """The indices of ``before`` (n, k) that ``after`` keeps: the collapse keeps the others' order."""
    kept, j = [], 0
    for i, point in enumerate(before):
        if j < len(after) and np.array_equal(point, after[j]):
            kept.append(i)
            j += 1
    assert j == len(after)
    return np.array(kept, np.int64)


@pytest.mark.slow
def test_the_two_cavity_shell_at_136000_cells_meets_the_bounds_again(monkeypatch):
    """benchmarks/optimize.md: before the collapse, 5 cells stayed below the bounds here (min dihedral 5.1 degrees,
    Q 0.008), flat against the RV cavity's wall where the surface triangulation folds; 634c4d9's optimizer met
    them (24.1 degrees, Q 0.342).  The bounds are the optimizer's own (issue 12)."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[3] / "benchmarks"))
    from shape_worker import SEED, make_input
    from bitemesh.core.parameters import ImplicitParameters, SpuriousParameters
    from bitemesh.core.sources.points import run
    _, points, normals, _ = make_input("two-cavity", 136000)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BitemeshWarning)
        result = run(points, normals, ImplicitParameters(), BitingParameters(cells=136000, seed=SEED),
                     SpuriousParameters())
    mesh = result.mesh
    assert check_valid_domain(mesh) == []
    assert radius_ratio(mesh.points, mesh.cells).min() >= 0.3
    assert np.nanmin(dihedral_angles(mesh.points, mesh.cells)) >= 20.0
