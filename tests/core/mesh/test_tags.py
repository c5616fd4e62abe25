"""Boundary and region tags (bitemesh.core.mesh.tags, bitemesh.core.mesh.interfaces): the surfaces of the real heart,
one tag per boundary piece of scattered points, regions of several labels that conform and follow their interface, and
the numbering and names on a hand-made mesh."""
from __future__ import annotations

from functools import cache
from pathlib import Path

import bitemesh
import numpy as np
import pytest
from bitemesh.core import shapes
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.mesh.interfaces import LabelRegions, label_regions
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid
from bitemesh.core.sources.points import run
from bitemesh.core.mesh.quality import radius_ratio
from bitemesh.core.mesh.simplicial import facet_measures
from bitemesh.core.mesh.tags import component_tags, enclosed_volume, region_tags
from bitemesh.io import read_labelled_points
from scipy.spatial import cKDTree

from tests.builders import PLAIN, cube_mesh, sphere_samples
from tests.meshcheck import assert_tagged, oriented_rows

PATIENT = Path(bitemesh.__file__).resolve().parent / "data" / "bivme_patient1" / "GPFile_000.txt"


# --- labelled contours: the demo heart ------------------------------------------------------------------------------

@cache
def heart():
    """The shipped biv-me patient at 20,000 cells (R about 3.5 mm; coarser, its cavities close at the base), the
    plain method: the tags are not the optimizer's business."""
    points, labels, slices = read_labelled_points(PATIENT)
    return run_labelled(points, labels, slices=slices, biting=BitingParameters(cells=20000), optimize=PLAIN)


def test_every_boundary_triangle_of_the_heart_is_on_a_named_surface():
    result = heart()
    mesh, function = result.mesh, result.function
    assert_tagged(mesh)
    assert mesh.tag_names == {"EPI": (1, 2), "LV_ENDO": (2, 2), "RV_ENDO": (3, 2), "BASE": (4, 2),
                              "MYOCARDIUM": (1, 3)}
    assert (mesh.cell_data["Region"] == 1).all()
    assert set(np.unique(mesh.facet_tags)) == {1, 2, 3, 4}
    centres = mesh.points[mesh.facets].mean(axis=1)
    # the BASE triangles lie on the base: their centroids within R / 3 of it (the plain method's boundary nodes are
    # on f = 0, not at its corners) but where a triangle spans one of its creases (it is linear on the triangles of
    # the annulus points, which meet at up to 80 degrees): within R there, and on the whole much nearer; every other
    # triangle lies below it but at the rim, where a triangle may straddle the base by R / 3 (by R / 2 at a crease)
    below = function.base.below(centres)
    base = mesh.facet_tags == 4
    assert np.abs(below[base]).max() < result.radius and np.median(np.abs(below[base])) < result.radius / 10
    assert (below[~base] > -result.radius / 2).all()
    # the base's triangles off its rim face out along its normal at one corner or at the centroid at least (one that
    # spans a crease may face away from the base's normal at its centroid: measured 2 of 178 at R = 3.7 mm; and from
    # it at every corner where it stands across a cliff of the base, the corners on the facets beyond: 1 of 190 at
    # R = 3.6 mm, 76 degrees from the base's normal at its centroid)
    edges = np.sort(np.concatenate([mesh.facets[:, [0, 1]], mesh.facets[:, [1, 2]], mesh.facets[:, [2, 0]]]), axis=1)
    owner = np.tile(base, 3)
    rim = {tuple(edge) for edge in edges[~owner].tolist()}
    inner = ~np.array([any(tuple(edge) in rim for edge in edges.reshape(3, -1, 2)[:, number].tolist())
                       for number in np.flatnonzero(base)])
    corners = mesh.points[mesh.facets[base][inner]]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facing = np.max([np.einsum("ij,ij->i", normals, function.base.outward(at))
                     for at in (*corners.transpose(1, 0, 2), corners.mean(axis=1))], axis=0)
    assert inner.sum() > 0.25 * base.sum() and (facing > 0).all()   # a band two or three R wide: a third inside
    # the others lie nearer to their own surface's contour points than to any other surface's
    trees = {name: cKDTree(function.points[name]) for name in ("EPI", "LV_ENDO", "RV_ENDO")}
    for tag, name in enumerate(trees, start=1):
        mine = centres[mesh.facet_tags == tag]
        near = {other: np.median(tree.query(mine)[0]) for other, tree in trees.items()}
        assert min(near, key=near.get) == name, near


# --- scattered points: one tag per boundary piece -----------------------------------------------------------------

@cache
def two_spheres(seed: int = 0):
    """A unit sphere and one of radius 0.5 beside it, as one scattered point set."""
    points, normals = sphere_samples(0.1)
    small = points * 0.5 + [3.0, 0.0, 0.0]
    return run(np.vstack([points, small]), np.vstack([normals, normals]), biting=BitingParameters(cells=3000,
                                                                                                 seed=seed),
               optimize=PLAIN).mesh


def test_two_spheres_give_two_boundary_tags_by_decreasing_area():
    mesh = two_spheres()
    assert_tagged(mesh)
    assert mesh.tag_names == {"BOUNDARY_1": (1, 2), "BOUNDARY_2": (2, 2), "DOMAIN": (1, 3)}
    centres = mesh.points[mesh.facets].mean(axis=1)
    for tag, centre, radius in ((1, [0, 0, 0], 1.0), (2, [3, 0, 0], 0.5)):
        distance = np.linalg.norm(centres[mesh.facet_tags == tag] - centre, axis=1)
        assert np.abs(distance - radius).max() < 0.1 * radius
    area = np.bincount(mesh.facet_tags, facet_measures(mesh.points[mesh.facets]))
    assert area[1] > area[2]


def test_same_input_and_seed_give_the_same_tags():
    first, again, other = two_spheres(), two_spheres.__wrapped__(), two_spheres(seed=1)
    assert np.array_equal(first.facets, again.facets) and np.array_equal(first.facet_tags, again.facet_tags)
    assert first.tag_names == again.tag_names
    assert not np.array_equal(first.points, other.points)   # the seed does reach the mesh


def test_a_hollow_ball_has_its_two_boundary_surfaces_apart():
    """One part, two boundary pieces: the outer sphere (larger) is BOUNDARY_1, the cavity BOUNDARY_2."""
    shell = shapes.sphere()
    grid = sample_function(lambda x: np.minimum(1 - np.linalg.norm(x, axis=1), np.linalg.norm(x, axis=1) - 0.5),
                           shell.lower, shell.upper, 0.04, margin=0.12)
    mesh = mesh_from_grid(grid, BitingParameters(radius=0.15), optimize=PLAIN).mesh
    assert_tagged(mesh)
    radii = np.linalg.norm(mesh.points[mesh.facets].mean(axis=1), axis=1)
    assert radii[mesh.facet_tags == 1].min() > 0.9 and radii[mesh.facet_tags == 2].max() < 0.6


# --- several labels: regions that conform -------------------------------------------------------------------------

R1, R2 = 6.0, 10.0   # a ball (label 2) inside a ball (label 1 the shell between)


def ball_grids(radius: float):
    """f of the union and of each label on a grid of spacing R / 4: (union, LabelRegions)."""
    spacing = radius / 4

    def grid(function):
        return sample_function(function, np.full(3, -R2), np.full(3, R2), spacing, margin=3 * spacing)

    def norm(x):
        return np.linalg.norm(x, axis=1)

    return grid(lambda x: R2 - norm(x)), LabelRegions({1: grid(lambda x: np.minimum(R2 - norm(x), norm(x) - R1)),
                                                       2: grid(lambda x: R1 - norm(x))})


def ball_in_ball(optimize: OptimizeParameters, radius: float = 1.25):
    union, regions = ball_grids(radius)
    return mesh_from_grid(union, BitingParameters(radius=radius), optimize=optimize, tagging=regions,
                          interfaces=regions).mesh, radius


@pytest.mark.parametrize("optimize", [PLAIN, OptimizeParameters()], ids=["plain", "default"])
def test_a_ball_in_a_ball_gives_two_regions_sharing_a_snapped_interface(optimize):
    mesh, radius = ball_in_ball(optimize)
    interface = assert_tagged(mesh)
    assert mesh.tag_names == {"BOUNDARY_1": (1, 2), "INTERFACE_1_2": (3, 2), "REGION_1": (1, 3), "REGION_2": (2, 3)}
    regions = mesh.cell_data["Region"]
    # the regions share exactly the nodes of the interface triangles, which are tagged by the pair
    shared = np.intersect1d(mesh.cells[regions == 1], mesh.cells[regions == 2])
    tagged = mesh.facets[mesh.facet_tags == 3]
    assert oriented_rows(tagged) == interface and np.array_equal(shared, np.unique(tagged))
    volumes = np.bincount(regions, signed_measures(mesh.points, mesh.cells))
    # oriented out of region 1 (the shell), into the inner ball: the divergence theorem over the closed interface
    # gives minus the inner ball's volume
    corners = mesh.points[tagged]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.einsum("ij,ij->", normal, corners.mean(axis=1)) / 6 == pytest.approx(-volumes[2], rel=1e-9)
    # Cut along the cells' centroids alone, the interface's nodes would lie about R / 3 off it (a staircase of
    # cell facets); sampled and snapped, most lie on it, and none beyond a long edge (1.5 R)
    off = np.abs(np.linalg.norm(mesh.points[np.unique(tagged)], axis=1) - R1) / radius
    assert np.median(off) < 0.15 and off.max() < 1.5, (np.median(off), off.max())
    # each region's volume is its ball's or shell's, within the chord error of facets about R wide on a sphere of
    # radius R1 (of the order of (R / R1)^2)
    exact = 4 / 3 * np.pi * np.array([R2**3 - R1**3, R1**3])
    assert np.abs(volumes[1:] / exact - 1).max() < (radius / R1) ** 2, volumes[1:] / exact - 1
    assert signed_measures(mesh.points, mesh.cells).min() > 0


def test_snapping_moves_only_interface_nodes_and_keeps_the_worst_cell():
    """On the union's mesh without interface nodes (the biting not told of the regions): the snap moves most of the
    staircase's nodes, no other node, and leaves no cell below min(the worst before, 0.3)."""
    union, regions = ball_grids(1.5)
    mesh = mesh_from_grid(union, BitingParameters(radius=1.5), optimize=PLAIN).mesh
    unsnapped, snapped = (label_regions(mesh, regions.functions, snap=snap) for snap in (False, True))
    moved = np.flatnonzero(np.linalg.norm(snapped.points - mesh.points, axis=1) > 0)
    interface = np.unique(snapped.facets[snapped.facet_tags == 3])
    assert np.array_equal(unsnapped.points, mesh.points) and np.array_equal(unsnapped.facets, snapped.facets)
    assert len(moved) > 0.5 * len(interface) and np.isin(moved, interface).all()
    assert radius_ratio(snapped.points, snapped.cells).min() >= min(radius_ratio(mesh.points, mesh.cells).min(), 0.3)
    off = [np.mean(np.abs(np.linalg.norm(state.points[interface], axis=1) - R1)) for state in (unsnapped, snapped)]
    assert off[1] < 0.8 * off[0], off


# --- numbering and names, on the unit cube in six tetrahedra ------------------------------------------------------

def test_tags_follow_from_the_labels_alone_and_interfaces_face_out_of_the_lower_label():
    cube = cube_mesh()
    mesh = region_tags(cube, np.where(cube.cell_data["Label"] == 1, 7, 3), [3, 7])
    interface = assert_tagged(mesh)
    assert mesh.tag_names == {"BOUNDARY_3": (1, 2), "BOUNDARY_7": (2, 2), "INTERFACE_3_7": (3, 2),
                              "REGION_3": (3, 3), "REGION_7": (7, 3)}
    assert len(interface) == np.count_nonzero(mesh.facet_tags == 3) > 0
    assert np.count_nonzero(mesh.facet_tags < 3) == 12   # the cube's 6 faces in 2 triangles each
    # a region of its own: the tags of the others do not move
    again = region_tags(cube, np.where(cube.cell_data["Label"] == 1, 7, 3), [3, 5, 7])
    assert again.tag_names["BOUNDARY_7"] == (3, 2) and again.tag_names["INTERFACE_3_7"] == (5, 2)


def test_one_region_tags_its_boundary_pieces():
    mesh = component_tags(cube_mesh(), region="SOLID")
    assert mesh.tag_names == {"BOUNDARY_1": (1, 2), "SOLID": (1, 3)} and len(mesh.facets) == 12


@pytest.mark.parametrize("labels", [[0, 1], [-2, 1], [2**31, 1]])
def test_a_region_label_outside_int32_or_not_positive_is_refused(labels):
    cube = cube_mesh()
    with pytest.raises(InvalidInputError, match=r"region labels must be whole numbers in \[1, 2147483647\].*"
                                                r"relabel the label map"):
        region_tags(cube, np.where(cube.cell_data["Label"] == 1, labels[0], labels[1]), labels)


def test_regions_that_are_not_among_the_labels_are_refused():
    cube = cube_mesh()
    with pytest.raises(InvalidInputError, match=r"regions must hold one of the labels \[1, 2\] for each of the 6"):
        region_tags(cube, np.full(6, 3), [1, 2])


# --- a label map of two labels, the user's path (SimpleITK) -------------------------------------------------------

VOXEL = 0.5


def two_boxes():
    """Two 10 mm cubes side by side along i (label 1 then label 2) and a third label beside them, 0.5 mm voxels."""
    labels = np.zeros((48, 24, 24), np.uint8)
    labels[2:22, 2:22, 2:22] = 1
    labels[22:42, 2:22, 2:22] = 2
    labels[44:47, 2:5, 2:5] = 3
    return labels


def test_a_label_map_of_two_labels_meshes_two_regions_and_their_interface():
    """Through a reflecting index-to-physical matrix (x = -i), which turns every cell and facet inside out until
    swapped back; labels 1 and 2 of three; the plain method (the optimizer's share: the ball in a ball)."""
    pytest.importorskip("SimpleITK")
    from bitemesh.labelmap import mesh_label_grid
    matrix = np.diag([-VOXEL, VOXEL, VOXEL, 1.0])
    matrix[:3, 3] = [30.0, -5.0, 2.0]
    result = mesh_label_grid(two_boxes(), matrix, labels=[1, 2], biting=BitingParameters(cells=4000), optimize=PLAIN)
    mesh, radius = result.mesh, result.radius
    assert_tagged(mesh)
    assert mesh.tag_names == {"BOUNDARY_1": (1, 2), "BOUNDARY_2": (2, 2), "INTERFACE_1_2": (3, 2),
                              "REGION_1": (1, 3), "REGION_2": (2, 3)}
    plane = 30.0 - VOXEL * 21.5    # halfway between the last voxel centre of label 1 and the first of label 2
    centres = mesh.points[mesh.cells].mean(axis=1)
    regions = mesh.cell_data["Region"]
    assert (regions[centres[:, 0] > plane + radius] == 1).all() and (regions[centres[:, 0] < plane - radius] == 2).all()
    interface = np.unique(mesh.facets[mesh.facet_tags == 3])
    off = np.abs(mesh.points[interface, 0] - plane) / radius
    assert np.median(off) < 0.15 and off.max() < 1.5, (np.median(off), off.max())
    # each box 1,000 mm^3, less what the nodes, about R apart, cut off its 8 sharp edges of 10 mm (a chamfer at most
    # R wide: R^2 / 2 a mm); the interface, within a tenth of R of its plane on average, moves at most
    # 100 mm^2 x R / 10 from one box to the other
    volumes = np.bincount(regions, mesh.cell_data["Volume"])[1:]
    assert (volumes < 1000).all() and (1000 - volumes).max() < 8 * 10 * radius**2 / 2, volumes
    assert abs(volumes[0] - volumes[1]) / 2 < 100 * radius / 10, volumes
    assert (mesh.cell_data["Volume"] > 0).all()


def test_a_cavity_open_at_its_base_is_closed_across_its_rim():
    """The unit cube's surface without its top (two triangles): the fan from the rim's centroid closes it flat, so
    the enclosed volume is the cube's, 1, exactly; the closed surface gives 1 too."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64)
    cells = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
    negative = signed_measures(corners, cells) < 0
    cells[negative] = cells[negative][:, [1, 0, 2, 3]]
    facets = boundary_facets(cells)
    top = (corners[facets][:, :, 2] == 1).all(axis=1)
    assert top.sum() == 2
    assert enclosed_volume(corners, facets) == pytest.approx(1.0, abs=1e-12)
    assert enclosed_volume(corners, facets[~top]) == pytest.approx(1.0, abs=1e-12)
