"""BiteMeshLogic hands every panel parameter to bitemesh: the optimizer's bounds (only when the optimizer is on), the
labelled contours' walls and plausibility switch, the margin, the handles and the fidelity bounds reach the core's
entry point for points, labelled contours and segments; a tighter optimizer bound changes the mesh as it changes
the core's; unknown names and bad bounds are refused before anything runs.

Run: cd /work/main && PYTHONPATH=filters .slicer-venv/bin/python -m pytest tests/slicer -q -p no:cacheprovider
Skipped where slicer-core is absent (the main environment).
"""
from __future__ import annotations

from bitemesh.core.sources.points import run as points_run
import bitemesh
import bitemesh.meshing
import numpy as np
import pytest
from bitemesh import InvalidInputError
from bitemesh.core.parameters import (BitingParameters, FidelityParameters, ImplicitParameters, OptimizeParameters,
                                      SpuriousParameters)

from tests.slicer.scenes import GPFILE, ball_segmentation, mesh_of, output_model, point_list, sphere_points

BOUNDS = {"iterations": 3, "min_dihedral": 25.0, "min_quality": 0.35}
COMMON = {"margin": 2.0, "handles": "keep", "far_samples": 1.0, "unsupported_area": 3.0, "allow_unfaithful": 1}
LABELLED = {"min_wall": 3.0, "rv_wall": 4.0, "allow_implausible": 1}


class Reached(Exception):
    """Raised by a stand-in for the core's entry point: what the logic handed it."""

    def __init__(self, arguments, keywords):
        super().__init__("reached the core")
        self.arguments, self.keywords = arguments, keywords


def stand_in(*arguments, **keywords):
    raise Reached(arguments, keywords)


def points_input(scene, monkeypatch, logic):
    monkeypatch.setattr(bitemesh.meshing, "run", stand_in)
    return point_list(scene, sphere_points(200))


def labelled_input(scene, monkeypatch, logic):
    monkeypatch.setattr(bitemesh.meshing, "run_labelled", stand_in)
    return logic.loadLabelledPoints(GPFILE, scene=scene)


def segment_input(scene, monkeypatch, logic):
    monkeypatch.setattr(bitemesh.meshing, "mesh_label_grid", stand_in)
    return ball_segmentation(scene, np.eye(3))[0]


def reached(logic, node, scene, **parameters):
    """The arguments the front door hands the core's entry point, by name (points and normals or labels: the
    positional ones)."""
    with pytest.raises(Reached) as caught:
        logic.process(node, output_model(scene), **parameters)
    arguments, keywords = caught.value.arguments, caught.value.keywords
    names = ("points", "normals or labels") if len(arguments) == 2 else ()
    return {**dict(zip(names, arguments)), **keywords}


@pytest.mark.parametrize("make_input", [points_input, labelled_input, segment_input])
def test_panel_parameters_reach_the_core(scene, logic, monkeypatch, make_input):
    node = make_input(scene, monkeypatch, logic)
    core = reached(logic, node, scene, optimize=1, **BOUNDS, **COMMON, **LABELLED)
    assert core["optimize"] == OptimizeParameters(optimize=1, **BOUNDS)
    assert core["implicit"].margin == 2.0 and core["spurious"].handles == "keep"
    assert core["fidelity"] == FidelityParameters(far_samples=1.0, unsupported_area=3.0, allow_unfaithful=1)
    if make_input is labelled_input:
        assert (core["min_wall"], core["rv_wall"], core["allow_implausible"]) == (3.0, 4.0, True)
    assert reached(logic, node, scene, optimize=0, **BOUNDS)["optimize"].optimize == 0   # the bounds alone: off


def test_the_panel_values_reach_the_core(scene, logic, monkeypatch):
    """As the Apply button does it: every parameter-node value, through coreParameters, into process."""
    node = labelled_input(scene, monkeypatch, logic)
    values = {spec.name: spec.default for spec in logic.parameterSpecs()}
    values.update(optimize=True, iterations=3, minDihedral=25.0, minQuality=0.35, rvWall=4.0, minWall=3.0, margin=2.0)
    core = reached(logic, node, scene, **logic.coreParameters(values))
    assert core["optimize"] == OptimizeParameters(optimize=1, **BOUNDS)
    assert (core["min_wall"], core["rv_wall"], core["allow_implausible"]) == (3.0, 4.0, False)
    assert core["implicit"].margin == 2.0
    values.update(minWall=-1.0, margin=-1.0)   # the automatic values
    core = reached(logic, node, scene, **logic.coreParameters(values))
    assert "min_wall" not in core and core["implicit"].margin is None   # automatic: the core's own default


def test_a_tighter_optimizer_bound_changes_the_mesh_as_in_bitemesh_run(scene, logic):
    """min_dihedral 40 degrees (default 20) sends the sliver removal further: another mesh, bitemesh.run's."""
    points = sphere_points(800)
    tight, default = output_model(scene), output_model(scene)
    logic.process(point_list(scene, points), tight, radius=5.0, optimize=1, min_dihedral=40.0)
    logic.process(point_list(scene, points), default, radius=5.0, optimize=1)
    expected = points_run(points, None, ImplicitParameters(), BitingParameters(radius=5.0), SpuriousParameters(),
                            optimize=OptimizeParameters(optimize=1, min_dihedral=40.0)).mesh
    mesh = mesh_of(tight)
    np.testing.assert_array_equal(mesh.cells, expected.cells)
    np.testing.assert_array_equal(mesh.points, expected.points)
    other = mesh_of(default)
    assert mesh.points.shape != other.points.shape or not np.array_equal(mesh.points, other.points)


def test_unknown_names_and_bad_bounds_are_refused(scene, logic, monkeypatch):
    node = points_input(scene, monkeypatch, logic)   # nothing may reach the core
    with pytest.raises(InvalidInputError, match=r"unknown parameter\(s\) min_dihedrals; known: .*min_dihedral"):
        logic.process(node, output_model(scene), optimize=1, min_dihedrals=25.0)
    with pytest.raises(InvalidInputError, match="unknown parameter.* minDihedral"):   # the panel's name
        logic.process(node, output_model(scene), minDihedral=25.0)
    with pytest.raises(InvalidInputError, match=r"min_quality must be in \[0, 1\)"):
        logic.process(node, output_model(scene), optimize=0, min_quality=1.0)
    with pytest.raises(InvalidInputError, match="rv_wall"):
        logic.process(node, output_model(scene), rv_wall=0.0)
    with pytest.raises(InvalidInputError, match="unknown panel parameter"):
        logic.coreParameters({"iteration": 3})
