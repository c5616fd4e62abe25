"""Meshes of any dimension to and from ``.npz`` and ``.h5`` (issue 36): the only formats that hold a 4-simplex; the
others refuse a k-D mesh by name and point to them."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bitemesh.core.errors import InvalidInputError
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid
from bitemesh.io import read_mesh, write_mesh


def ball_mesh(k: int) -> Mesh:
    """A coarse k-ball, tagged (one boundary, one region) and with its quality arrays, and a point array."""
    grid = sample_function(lambda x: 1 - np.linalg.norm(x, axis=1), -np.ones(k), np.ones(k), 0.1, margin=0.2)
    mesh = mesh_from_grid(grid, BitingParameters(radius=0.4), optimize=OptimizeParameters(optimize=0)).mesh
    return mesh.with_point_data(Radius=np.linalg.norm(mesh.points, axis=1))


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
@pytest.mark.parametrize("k", [3, 4, 5])
def test_a_k_d_mesh_round_trips(tmp_path, k, suffix):
    """Points, cells, tagged facets, names, every cell and point array and the unit come back bit for bit."""
    mesh = replace(ball_mesh(k), unit="m")
    write_mesh(mesh, tmp_path / f"ball{suffix}")
    assert [path.name for path in tmp_path.iterdir()] == [f"ball{suffix}"]
    back = read_mesh(tmp_path / f"ball{suffix}")
    assert back.points.shape[1] == k and np.array_equal(back.points, mesh.points)
    assert np.array_equal(back.cells, mesh.cells) and np.array_equal(back.facets, mesh.facets)
    assert np.array_equal(back.facet_tags, mesh.facet_tags) and back.tag_names == mesh.tag_names
    assert set(back.cell_data) == set(mesh.cell_data) >= {"Region", "RadiusRatio"}
    for name, array in mesh.cell_data.items():
        assert np.array_equal(back.cell_data[name], array), name
    assert np.array_equal(back.point_data["Radius"], mesh.point_data["Radius"]) and back.unit == mesh.unit


@pytest.mark.parametrize("suffix", [".vtu", ".xdmf", ".msh", ".pts", ""])
def test_a_4_d_mesh_is_refused_where_no_4_simplex_fits(tmp_path, suffix):
    with pytest.raises(InvalidInputError, match=r"a 4-D mesh can be written to \.npz or \.h5 only"):
        write_mesh(ball_mesh(4), tmp_path / f"ball{suffix}")
    assert list(tmp_path.iterdir()) == []


def test_a_file_that_is_not_a_bitemesh_mesh_is_named(tmp_path):
    import h5py
    np.savez(tmp_path / "other.npz", values=np.arange(3))
    with h5py.File(tmp_path / "other.h5", "w") as h5:   # an XDMF file's HDF5 companion, say
        h5.create_dataset("Mesh/geometry", data=np.zeros((4, 3)))
    (tmp_path / "text.h5").write_text("not HDF5")
    for name in ("other.npz", "other.h5", "text.h5"):
        with pytest.raises(InvalidInputError, match=rf"'{tmp_path / name}': not a bitemesh \.(npz|h5) mesh"):
            read_mesh(tmp_path / name)
