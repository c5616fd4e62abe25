"""Labelled contours in the VTK filters: points with a ``Label`` (and ``Slice``) point array go through
PointsToImplicit (Domain, BasePlane, MinWall) and the rest of the chain, or through MeshFromPoints in one step,
and give what the core gives.

The synthetic case is the two-cavity shell of tests/builders.py, sampled whole (no base plane): a closed
ellipsoidal shell with two closed cavities, whose volume is known.
"""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.algorithms import MeshFromPoints, PointsToImplicit
from bitemesh.convert import image_to_grid, unstructured_to_mesh, vtk_points
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.steps.spine import GRID_PER_RADIUS
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonDataModel import vtkPolyData

from tests.builders import PLAIN, SHELL_DOMAIN, SHELL_VOLUME, chain, closed_shell_contours, labelled_polydata
from tests.meshcheck import assert_valid_domain

CELLS = 6000


@pytest.fixture(scope="module")
def closed_shell():
    """The whole shell's contours (short-axis slices over its full height) and their vtkPolyData."""
    points, labels, slices = closed_shell_contours()
    return points, labels, slices, labelled_polydata(points, labels, slices)


def test_mesh_from_points_meshes_labelled_contours_as_the_core_does(closed_shell):
    points, labels, slices, data = closed_shell
    one_step = MeshFromPoints()
    one_step.SetInputData(data)
    one_step.SetCells(CELLS)
    one_step.SetDomain(SHELL_DOMAIN)
    one_step.SetBasePlane("none")
    one_step.SetOptimize(0)   # the plain method: the filter reaches the core's labelled path (walls ~1 cell thick)
    mesh = unstructured_to_mesh(one_step.update())
    core = run_labelled(points, labels, domain=SHELL_DOMAIN, base_plane="none", slices=slices,
                        biting=BitingParameters(cells=CELLS), optimize=PLAIN).mesh
    np.testing.assert_array_equal(mesh.cells, core.cells)
    np.testing.assert_allclose(mesh.points, core.points, atol=1e-9)
    assert_valid_domain(mesh, euler=6, components=1, measure=SHELL_VOLUME, measure_tolerance=0.03,
                        mean_quality=0.75)


def test_the_five_filter_chain_meshes_labelled_contours(closed_shell):
    *_, data = closed_shell
    radius = (5.4 * SHELL_VOLUME / CELLS) ** (1 / 3)
    pipeline = chain(data, radius=radius, grid_spacing=radius / GRID_PER_RADIUS)
    implicit, biting, quality = pipeline.implicit, pipeline.biting, pipeline.quality
    implicit.SetDomain(SHELL_DOMAIN)
    implicit.SetBasePlane("none")
    mesh = unstructured_to_mesh(quality.update())
    assert_valid_domain(mesh, euler=6, components=1, measure=SHELL_VOLUME, measure_tolerance=0.03,
                        mean_quality=0.75)
    # the image is f of the domain: positive in the wall between the cavities, negative inside each cavity
    grid = image_to_grid(implicit.GetOutputDataObject(0))
    wall, lv, rv = [-5.0, 0, -20], [15.0, 0, -20], [-27.5, 0, -20]
    assert grid.evaluate(np.array([wall])) > 0 > grid.evaluate(np.array([lv, rv])).max()
    # a change downstream, of the grid or of the wall does not fit the surfaces again; a change of the domain does
    fitted = implicit._source[1]
    biting.SetRadius(1.1 * radius)
    implicit.SetMinWall(3.0)
    quality.update()
    assert implicit._source[1] is fitted
    implicit.SetDomain("EPI - LV_ENDO")
    implicit.update()
    assert implicit._source[1] is not fitted
    assert image_to_grid(implicit.GetOutputDataObject(0)).evaluate(np.array([rv])) > 0   # the RV cavity is filled


def test_the_thinnest_wall_follows_the_grid_or_min_wall(closed_shell):
    *_, data = closed_shell
    implicit = PointsToImplicit()
    implicit.SetInputData(data)
    implicit.SetDomain(SHELL_DOMAIN)
    implicit.SetBasePlane("none")
    implicit.SetRadius(8.0)   # the thinnest wall follows R unless min_wall is given
    implicit.SetGridSpacing(2.0)
    default = image_to_grid(implicit.update()).inside_volume()
    implicit.SetMinWall(0.0)
    thinnest = image_to_grid(implicit.update()).inside_volume()
    implicit.SetMinWall(14.0)   # thicker than the shell's thinnest wall (11.5 mm between EPI and RV_ENDO)
    thick = image_to_grid(implicit.update()).inside_volume()
    assert thinnest < default < thick
    assert thinnest == pytest.approx(SHELL_VOLUME, rel=0.03)


@pytest.mark.parametrize("setting, message", [
    ({"SetDomain": "EPI - LV_ENDO - AORTA"}, "unknown surface 'AORTA'"),
    ({"SetDomain": "EPI -"}, "domain"),
    ({"SetBasePlane": "valves"}, "base_plane='valves' needs at least 3 points"),
    ({"SetBasePlane": "top"}, "base_plane"),
    ({"SetMinWall": -2.0}, "min_wall"),   # -1 is the automatic value
])
def test_bad_labelled_settings_are_reported_with_their_name(closed_shell, vtk_errors, setting, message):
    *_, data = closed_shell
    for algorithm in (PointsToImplicit(), MeshFromPoints()):
        algorithm.SetInputData(data)
        algorithm.SetDomain(SHELL_DOMAIN)
        for name, value in setting.items():
            getattr(algorithm, name)(value)
        with pytest.raises(InvalidInputError, match=message):
            algorithm.update()
        assert algorithm.GetOutputDataObject(0).GetNumberOfPoints() == 0
        assert message.split()[0] in vtk_errors.text()
        vtk_errors.clear()


def test_labels_that_are_non_integer_numbers_are_refused(closed_shell, vtk_errors):
    points, *_ = closed_shell
    data = vtkPolyData()
    data.SetPoints(vtk_points(points))
    labels = numpy_to_vtk(np.linspace(0.5, 3.5, len(points)), deep=True)
    labels.SetName("Label")
    data.GetPointData().AddArray(labels)
    algorithm = MeshFromPoints()
    algorithm.SetInputData(data)
    with pytest.raises(InvalidInputError, match="non-integer"):
        algorithm.update()
    vtk_errors.clear()


@pytest.mark.slow
def test_mesh_from_points_takes_cardiac_data_as_it_comes(shared_data, tmp_path, vtk_errors):
    """A GPFile like a real export (4x denser, no RV epicardium, no outflow valves, labels without prefix) as a
    VTP's Label and Slice arrays: the front door reads from it what it reads from the file (points, labels, slices:
    hence the core's mesh of tests/cli/test_cardiac_variants.py, bit for bit: tests/core/test_threads.py and the
    batch's tests hold the meshing deterministic, and that test the RV epicardium derived), and the filter gives a
    valid heart at R = 2 mm."""
    from bitemesh.convert import plan_of
    from bitemesh.io import read_labelled_points
    from bitemesh.meshing import read_input
    from bitemesh.options import as_options
    from tests.cardiac_variants import read_gpfile, unprefixed, variant_file, write_gpfile
    path = variant_file(shared_data / "bivme_patient1" / "GPFile_000.txt", "like GPFile of issue 10", tmp_path)
    path = write_gpfile(unprefixed(read_gpfile(path)), tmp_path / "GPFile_unprefixed.txt")
    points, labels, slices = read_labelled_points(path)
    data = labelled_polydata(points, labels, slices)
    from_file, from_vtp = (read_input(given, as_options(None)) for given in (path, data))
    np.testing.assert_array_equal(from_vtp.points, from_file.points)
    np.testing.assert_array_equal(from_vtp.labels, from_file.labels)
    np.testing.assert_array_equal(from_vtp.slices, from_file.slices)
    one_step = MeshFromPoints()
    one_step.SetInputData(data)
    # the reading is tested here; the optimizer on a heart in tests/core/sources/test_bivme_patient
    one_step.SetOptimize(0)
    output = one_step.update()
    mesh = unstructured_to_mesh(output)
    assert plan_of(output)["Radius"] == 2.0
    assert_valid_domain(mesh, euler=2, components=1)   # its handles, thinner than a cell, removed
    assert vtk_errors.messages() == [], vtk_errors.text()


@pytest.mark.slow
def test_the_five_filter_chain_cuts_no_wall_from_a_cavity_to_the_epicardium(shared_data, vtk_errors):
    """Cine frame 15 through the five filters at R = 2 mm: its handle repair had a cut of 278 cells from the RV
    cavity to the epicardium to choose (the core refuses it: handles._joins_surfaces), and the chain, whose
    SpuriousCellFilter had only f on the image, took it.  PointsToImplicit now puts which surface gives f near each
    node on the image (DataSurface): the chain's domain is the core's, cell for cell, one part, Euler 2."""
    from bitemesh.io import read_labelled_points
    from bitemesh.core.mesh.simplicial import signed_measures
    path = shared_data / "bivme_patient1_cine" / "guidepoints" / "GPFile_015.txt"
    if not path.is_file():
        pytest.skip(f"no biv-me cine in {path.parent}")
    points, labels, slices = read_labelled_points(path)
    pipeline = chain(labelled_polydata(points, labels, slices), radius=2.0, cells=None)
    mesh = unstructured_to_mesh(pipeline.spurious.update())
    core = run_labelled(points, labels, slices=slices, optimize=PLAIN, allow_implausible=True)
    assert len(mesh.cells) == len(core.mesh.cells)
    assert signed_measures(mesh.points, mesh.cells).sum() == pytest.approx(core.mesh.cell_data["Volume"].sum(),
                                                                            rel=1e-9)
    assert_valid_domain(mesh, euler=2, components=1)
    assert vtk_errors.messages() == [], vtk_errors.text()


def test_contours_of_several_time_frames_are_refused_by_the_filters(closed_shell, vtk_errors):
    """A GPFile of two frames read as a table in ParaView: a Label, a Slice and a 'time frame' array; one slice
    holding two frames is not one heart."""
    points, labels, slices, _ = closed_shell
    data = labelled_polydata(np.vstack([points, points * 1.1]), np.r_[labels, labels], np.r_[slices, slices])
    frames = numpy_to_vtk(np.r_[np.zeros(len(points)), np.ones(len(points))], deep=True)
    frames.SetName("time frame")
    data.GetPointData().AddArray(frames)
    one_step = MeshFromPoints()
    one_step.SetInputData(data)
    with pytest.raises(InvalidInputError, match=r"several time frames \(0 \(\d+ points\), 1 .*Threshold"):
        one_step.update()
    assert "several time frames" in vtk_errors.text()
