"""Run by tests/solvers in a Python that has DOLFINx (the PyPI wheel dolfinx-solver-real), cardiac-geometriesx and
fenicsx-ldrb, not bitemesh: load bitemesh's files as their users do and print what they found as JSON.

Usage: python solver_check.py TARGET...; prints {TARGET: what was found} as one JSON line.  A TARGET is a
cardiac-geometries folder, or HEART.xdmf (bitemesh's XDMF with fibres: read as docs/solvers.md shows, ldrb run with
bitemesh's angles on DG0, the two compared).  One process for all: DOLFINx takes seconds to import."""
import json
import sys
import time

import h5py  # noqa: F401  (before dolfinx: the wheel's HDF5 and h5py's must load in this order)
import dolfinx_solver  # noqa: F401  (the wheel: before dolfinx)
import dolfinx
import numpy as np
import ufl
from mpi4py import MPI


def main(folder: str) -> dict:
    import cardiac_geometries
    import ldrb
    from cardiac_geometries.mesh import transform_markers

    geometry = cardiac_geometries.geometry.Geometry.from_folder(MPI.COMM_WORLD, folder)
    mesh, facets = geometry.mesh, geometry.ffun
    found = {"markers": {name: list(map(int, value)) for name, value in geometry.markers.items()},
             "cells": int(mesh.topology.index_map(3).size_local),
             "cell_tags": sorted(set(map(int, geometry.cfun.values))),
             "facet_counts": {int(tag): int(np.sum(facets.values == tag)) for tag in set(facets.values)}}
    for name, tags in (("edge_counts", geometry.efun), ("vertex_counts", geometry.vfun)):
        if tags is not None:
            found[name] = {int(tag): int(np.sum(tags.values == tag)) for tag in set(tags.values)}
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facets)
    found["areas"] = {name: dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ds(int(value[0]))))
                      for name, value in geometry.markers.items() if int(value[1]) == 2}
    found["volume"] = dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ufl.dx(domain=mesh)))
    start = time.perf_counter()
    system = ldrb.dolfinx_ldrb(mesh=mesh, ffun=facets, markers=transform_markers(geometry.markers))
    fibre = system.f0.x.array.reshape(-1, 3)
    found["ldrb"] = {"seconds": time.perf_counter() - start, "unit": float(np.abs(np.linalg.norm(fibre, axis=1)
                                                                                     - 1).max())}
    return found


def compare_fibres(path: str) -> dict:
    """bitemesh's Fibre (the HDF5 dataset /CellData/Fibre, by its name) against ldrb's DG0 fibres with the same
    angles: the angle between the two fibre lines in each cell (degrees)."""
    import ldrb
    from dolfinx.io import XDMFFile

    with XDMFFile(MPI.COMM_WORLD, path, "r") as xdmf:
        mesh = xdmf.read_mesh(name="Grid")
        names = json.loads(xdmf.read_information("tag_names", "/Xdmf/Domain/Grid"))
    mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
    with XDMFFile(MPI.COMM_WORLD, path.replace(".xdmf", "_facets.xdmf"), "r") as xdmf:
        facets = xdmf.read_meshtags(mesh, name="Grid")
    angles = {f"{kind}_{wall}_{side}": value for kind, values in (("alpha", (40.0, -50.0)), ("beta", (-65.0, 25.0)))
              for side in ("lv", "rv") for wall, value in zip(("endo", "epi"), values)}
    markers = {name.lower().replace("_endo", ""): [value[0]] for name, value in names.items() if value[1] == 2}
    system = ldrb.dolfinx_ldrb(mesh=mesh, ffun=facets, markers=markers, fiber_space="DG_0", **angles)
    theirs = system.f0.x.array.reshape(-1, 3)
    with h5py.File(path.replace(".xdmf", ".h5"), "r") as h5:
        ours = np.asarray(h5["/CellData/Fibre"])[mesh.topology.original_cell_index]
    cells = mesh.topology.index_map(3).size_local
    dofs = system.f0.function_space.dofmap.list[:cells, 0]
    cosine = np.abs(np.sum(theirs[dofs] * ours[:cells], axis=1)) / np.linalg.norm(theirs[dofs], axis=1)
    degrees = np.degrees(np.arccos(np.clip(cosine, 0, 1)))
    return {"cells": int(cells), "median": float(np.median(degrees)), "p90": float(np.percentile(degrees, 90)),
            "markers": markers}


if __name__ == "__main__":
    print(json.dumps({target: compare_fibres(target) if target.endswith(".xdmf") else main(target)
                      for target in sys.argv[1:]}))
