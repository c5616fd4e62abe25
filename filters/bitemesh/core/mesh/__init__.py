"""The simplicial mesh and what is measured on it: topology, adjacency, validity, quality, tags, regions."""
