"""The meshing steps of the paper (biting, Delaunay, spurious cells) with the repair, the handles, the fidelity check
and the spine that runs them."""
