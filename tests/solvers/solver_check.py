"""Run by tests/solvers/test_solver_folders.py in a Python that has DOLFINx (the PyPI wheel dolfinx-solver-real),
cardiac-geometriesx and fenicsx-ldrb, not bitemesh: load a bitemesh folder as their users do and print what they
found as JSON.  Usage: python solver_check.py FOLDER."""
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


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1])))
