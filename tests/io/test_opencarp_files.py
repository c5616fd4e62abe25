"""openCARP's text format (``.pts``): the tagged cube and rectangle round trip (points in micrometres on disk, the
regions, the fibres, the surfaces with their names), and openCARP's own meshtool (pymeshtool, PyPI) reads what
bitemesh writes as it reads its own: the same nodes in micrometres, the regions as element tags, no cell it counts as
inverted, the fibres, the boundary it extracts being the tagged surfaces turned as it turns them, the node sets."""
from __future__ import annotations

import json

import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.io import mesh_files, read_mesh, write_mesh

from tests.io.test_tagged_files import cube, facet_set, rectangle


def with_fibres(mesh: Mesh) -> Mesh:
    """``mesh`` with orthonormal Fibre, Sheet and SheetNormal a cell (turning from cell to cell)."""
    angle = np.linspace(0, np.pi, len(mesh.cells))
    fibre = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1)
    sheet = np.stack([-np.sin(angle), np.cos(angle), np.zeros_like(angle)], axis=1)
    return mesh.with_cell_data(Fibre=fibre, Sheet=sheet, SheetNormal=np.cross(fibre, sheet))


@pytest.mark.parametrize("make", [cube, rectangle])
def test_the_files_round_trip_with_tags_and_fibres(tmp_path, make):
    mesh = with_fibres(make()) if make is cube else make()
    path = tmp_path / "heart.pts"
    write_mesh(mesh, path)
    surfaces = [name for name, (_, dimension) in mesh.tag_names.items() if dimension == mesh.dim - 1]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [p.name for p in mesh_files(path)] + [f"heart_{name}{suffix}" for name in surfaces
                                              for suffix in (".surf", ".vtx")])
    on_disk = np.loadtxt(path, skiprows=1)
    np.testing.assert_allclose(on_disk[:, :mesh.dim], 1000 * mesh.points, rtol=1e-15)
    back = read_mesh(path)
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    np.testing.assert_array_equal(back.cell_data["Region"], mesh.cell_data["Region"])
    assert facet_set(back.facets, back.facet_tags) == facet_set(mesh.facets, mesh.facet_tags)
    assert back.tag_names == mesh.tag_names
    assert json.loads((tmp_path / "heart_tags.json").read_text())["LEFT"] == [1, mesh.dim]
    if "Fibre" in mesh.cell_data:
        for name in ("Fibre", "Sheet", "SheetNormal"):
            np.testing.assert_allclose(back.cell_data[name], mesh.cell_data[name], atol=1e-8)
    else:
        assert "Fibre" not in back.cell_data


def test_meshtool_reads_the_mesh_as_its_own(tmp_path):
    meshtool = pytest.importorskip("pymeshtool")
    mesh = with_fibres(cube())
    write_mesh(mesh, tmp_path / "heart.pts")
    read = meshtool.Mesh(str(tmp_path / "heart"), format="carp_txt", num_fibers=2)
    assert (read.num_points, read.num_elements) == (len(mesh.points), len(mesh.cells))
    np.testing.assert_allclose(read.points, 1000 * mesh.points, rtol=1e-12)
    np.testing.assert_array_equal(read.element_tags, mesh.cell_data["Region"])
    _, _, connectivity, _ = read.elements
    np.testing.assert_array_equal(connectivity.reshape(-1, 4), mesh.cells)
    # meshtool's quality is 0 for the regular tetrahedron, 1 for a flat one and above 1 for an inverted one
    assert read.query_quality().max() < 1
    fibres = np.asarray(read.fibers).reshape(len(mesh.cells), -1)
    np.testing.assert_allclose(fibres, np.hstack([mesh.cell_data["Fibre"], mesh.cell_data["Sheet"]]), atol=1e-8)
    boundary = read.extract_surface(reindex_nodes=False)[0]
    _, _, triangles, _ = boundary.elements
    ours = mesh.facets[np.isin(mesh.facet_tags, [mesh.tag_names[name][0] for name in ("WALL_1", "WALL_2", "BOTTOM")])]
    assert facet_set(triangles.reshape(-1, 3), np.zeros(len(ours))) == facet_set(ours[:, ::-1], np.zeros(len(ours)))
    assert len(ours) == len(boundary_facets(mesh.cells))
    nodes, domain = meshtool.load_vtx(str(tmp_path / "heart_BOTTOM.vtx"))
    bottom = mesh.facets[mesh.facet_tags == mesh.tag_names["BOTTOM"][0]]
    assert domain == "intra" and nodes.tolist() == np.unique(bottom).tolist()


def test_a_tag_name_that_cannot_name_a_file_is_refused(tmp_path):
    mesh = cube()
    names = dict(mesh.tag_names)
    names["LV/ENDO"] = names.pop("BOTTOM")
    with pytest.raises(InvalidInputError, match=r"LV/ENDO.*openCARP"):
        write_mesh(Mesh(mesh.points, mesh.cells, mesh.cell_data, mesh.facets, mesh.facet_tags, names),
                   tmp_path / "heart.pts")
    assert list(tmp_path.iterdir()) == []
