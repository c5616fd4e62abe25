"""bitemesh: tetrahedral meshes from scattered points, after Schaerer et al. ("biting" node placement)."""
__version__ = "0.1.0"
