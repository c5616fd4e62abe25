"""The MeshOptimizer: relaxation, Delaunay and quality flips, smoothing, sliver removal, collapses."""
