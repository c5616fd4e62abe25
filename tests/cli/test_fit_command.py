"""``bitemesh fit``: the shipped heart's frame 0 meshed once (20,000 cells) and deformed onto other frames of biv-me
patient1's cine cycle as a new user would: one frame to a mesh, a cycle to a ParaView time series.  The bounds are
the issue's (wall guide points mean <= 1.0 mm, 95 % <= 3.0 mm, no inverted cell) and biv-me's: its own fitted LV
endocardium lies about 1.2 mm from the same guide points, which over an end-systolic LV surface of ~100 cm^2 is
~12 ml of ~80, so the fitted cavity must be within 15 % of the volume biv-me's surface encloses."""
from __future__ import annotations

import re

import numpy as np
import pytest
from bitemesh.core.fem.template import fit_template
from bitemesh.core.mesh.tags import cavity_volumes, enclosed_volume
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.optimize.measures import mean_edge_length
from bitemesh.core.sources.contours.cardiac import BIVME_SURFACES, canonical_labels
from bitemesh.core.sources.contours.registration import registered
from bitemesh.core.mesh.simplicial import facet_measures
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.fitting import frame_base
from bitemesh.io import read_labelled_points, read_mesh

from tests.cardiac_variants import read_surface
from tests.meshcheck import assert_valid_domain
from bitemesh import cli

WALL_WORDS = ("ENDOCARDIAL", "EPICARDIAL", "FREEWALL", "SEPTUM")


def gpfile(folder, frame: int):
    return folder / "guidepoints" / f"GPFile_{frame:03d}.txt"


def wall_points(points, labels, slices) -> np.ndarray:
    """(n, 3) the wall guide points (every ENDO / EPI / FREEWALL / SEPTUM point of the slices kept) where the fit
    takes them: their slices moved back from their breath-hold shifts, as the mesher moves them."""
    points, labels, _, _ = registered(points, canonical_labels(labels)[0], slices, BIVME_SURFACES)
    return points[[any(word in label for word in WALL_WORDS) for label in labels]]


def bivme_lv_volume(folder, frame: int) -> float:
    """ml enclosed by biv-me's fitted LV endocardium of ``frame``, closed across its valve rings."""
    return enclosed_volume(*read_surface(folder / "fitted" / f"patient1_LV_ENDOCARDIAL_{frame:03d}.vtk")) / 1000


def test_end_systole_fitted_from_end_diastole(cine, tmp_path, capsys):
    """Frame 8 (end-systole) from the frame-0 template in one command: the same cells and tags, a valid domain,
    every wall guide point close, the LV cavity as biv-me's."""
    folder, template_path = cine
    output = tmp_path / "es.vtu"
    assert cli.main(["fit", str(template_path), str(gpfile(folder, 8)), "-o", str(output)]) == 0
    assert "data to the boundary mean" in capsys.readouterr().out
    template, fitted = read_mesh(template_path), read_mesh(output)
    np.testing.assert_array_equal(fitted.cells, template.cells)
    assert fitted.tag_names == template.tag_names
    assert_valid_domain(fitted)
    wall = wall_points(*read_labelled_points(gpfile(folder, 8)))
    distance = distances_to_facets(wall, fitted.points[boundary_facets(fitted.cells)])
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0
    assert cavity_volumes(fitted)["LV_ENDO"] / 1000 == pytest.approx(bivme_lv_volume(folder, 8), rel=0.15)


def test_a_cycle_is_a_time_series_with_its_volumes(cine, tmp_path, capsys):
    """Frames 0, 4, 8 as a cycle: a .pvd naming one .vtu a frame (all with the template's cells), the LV emptying
    from frame to frame, end-diastole frame 0, end-systole frame 2, the ejection fraction printed as computed; at
    end-systole the walls end at the base the mesher puts on the frame: no more than two facets' area of them
    stands more than a mean edge above it (a tilted base's rounding; 1.1 cm2, 22 facets, up to 8 mm when the valve
    points alone pulled the template's base)."""
    folder, template_path = cine
    output = tmp_path / "cycle.pvd"
    frames = [str(gpfile(folder, frame)) for frame in (0, 4, 8)]
    assert cli.main(["fit", str(template_path), *frames, "-o", str(output)]) == 0
    printed = capsys.readouterr().out
    names = re.findall(r'file="([^"]+)"', output.read_text())
    assert names == ["cycle_000.vtu", "cycle_001.vtu", "cycle_002.vtu"]
    template = read_mesh(template_path)
    lv = []
    for name in names:
        fitted = read_mesh(tmp_path / name)
        np.testing.assert_array_equal(fitted.cells, template.cells)
        lv.append(cavity_volumes(fitted)["LV_ENDO"] / 1000)
    assert lv[0] > lv[1] > lv[2]
    assert "end-diastole: frame 0" in printed and "end-systole: frame 2" in printed
    assert f"ejection fraction {100 * (lv[0] - lv[2]) / lv[0]:.1f} %" in printed
    points, labels, slices = read_labelled_points(gpfile(folder, 8))
    points, labels, slices, _ = registered(points, canonical_labels(labels)[0], slices, BIVME_SURFACES)
    base = frame_base(points, labels, slices)
    walls = fitted.points[fitted.facets[np.isin(fitted.facet_tags, [fitted.tag_names[name][0]
                                                                    for name in ("EPI", "LV_ENDO", "RV_ENDO")])]]
    area = facet_measures(walls)
    edge = mean_edge_length(fitted.points, fitted.cells)
    assert area[base.below(walls.mean(axis=1)) < -edge].sum() <= 2 * np.sqrt(3) / 4 * edge ** 2


def test_the_template_fitted_twice_gives_the_same_mesh(cine):
    folder, template_path = cine
    template = read_mesh(template_path)
    points, labels, _ = read_labelled_points(gpfile(folder, 4))
    data = {"EPI": points[np.char.find(labels.astype(str), "EPICARDIAL") >= 0],
            "LV_ENDO": points[np.char.find(labels.astype(str), "LV_ENDOCARDIAL") >= 0]}
    first, second = (fit_template(template, data).mesh.points for _ in range(2))
    np.testing.assert_array_equal(first, second)


@pytest.mark.parametrize("scale", [0.8, 1.3])
def test_another_patient_sized_turned_and_placed_elsewhere(cine, scale):
    """A stand-in for another patient's end-systole: frame 8 turned 29 degrees, stretched 1.15 / 1.0 / 0.9, scaled
    by 0.8 or 1.3 and moved 95 mm (scanner coordinates): the issue's accuracy bounds (1.0 mm mean, 3.0 at 95 %) to
    the registered wall guide points, times the scale when it enlarges (the 20,000 cells stretch with the heart, and
    so does the distance between a facet and the contours it passes between), a valid domain, and the smallest
    dihedral angle no lower than the template's (or the 10-degree floor) less 1 degree (the floor lets a cell
    already under it lose 0.1 degree a step)."""
    from bitemesh import Samples, fit
    from bitemesh.core.mesh.quality import quality_summary
    folder, template_path = cine
    template = read_mesh(template_path)
    points, labels, slices = read_labelled_points(gpfile(folder, 8))
    turn = np.array([[np.cos(0.5), -np.sin(0.5), 0.0], [np.sin(0.5), np.cos(0.5), 0.0], [0.0, 0.0, 1.0]])
    centre = points.mean(axis=0)
    moved = scale * (points - centre) @ np.diag([1.15, 1.0, 0.9]) @ turn.T + centre + [80.0, -40.0, 25.0]
    fitted = fit(template, Samples(moved, labels=labels, slices=slices)).mesh
    assert_valid_domain(fitted)
    distance = distances_to_facets(wall_points(moved, labels, slices), fitted.points[boundary_facets(fitted.cells)])
    grown = max(scale, 1.0)
    assert distance.mean() <= 1.0 * grown and np.percentile(distance, 95) <= 3.0 * grown
    assert quality_summary(fitted).angle_min >= min(quality_summary(template).angle_min, 10.0) - 1.0


@pytest.mark.parametrize("output, extra, words", [
    ("cycle.pvd", ["--frame", "0"], "--frame picks a frame of one GPFile"),
    ("cycle.vtu", [], "name a .pvd file"),
    ("cycle.pvd", ["--pull", "0"], "pull must be in (0, inf]"),
])
def test_a_cycle_refuses_what_does_not_apply(cine, tmp_path, capsys, output, extra, words):
    folder, template_path = cine
    assert cli.main(["fit", str(template_path), str(gpfile(folder, 0)), str(gpfile(folder, 1)),
                     "-o", str(tmp_path / output), *extra]) == 1
    assert words in capsys.readouterr().err


def test_slices_shifted_by_breath_holds_fit_as_the_unshifted_frame(cine, tmp_path, capsys):
    """Frame 8 with every short-axis slice moved 2-5 mm in its plane (tests/cardiac_variants.py): the fit registers
    the slices as the mesher does (a note says so), so its boundary lies where the unshifted frame's fit lies: the
    unshifted frame's wall guide points within the issue's bounds (1.0 mm mean, 3.0 at 95 %) of it, and the LV cavity
    within 3 % of the unshifted fit's (the shifts are found within 1 mm: tests/core/sources)."""
    from tests.cardiac_variants import read_frame, shifted_slices, write_gpfile
    folder, template_path = cine
    shifted = write_gpfile(shifted_slices(read_frame(folder / "guidepoints", 8), seed=1)[0], tmp_path / "GPFile.txt")
    meshes = {}
    for name, data in (("shifted", shifted), ("as traced", gpfile(folder, 8))):
        assert cli.main(["fit", str(template_path), str(data), "-o", str(tmp_path / f"{name}.vtu")]) == 0
        meshes[name] = read_mesh(tmp_path / f"{name}.vtu")
        if name == "shifted":
            assert "slices moved in their planes" in capsys.readouterr().err
    wall = wall_points(*read_labelled_points(gpfile(folder, 8)))
    distance = distances_to_facets(wall, meshes["shifted"].points[boundary_facets(meshes["shifted"].cells)])
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0
    volumes = [cavity_volumes(meshes[name])["LV_ENDO"] for name in ("shifted", "as traced")]
    assert volumes[0] == pytest.approx(volumes[1], rel=0.03)
