"""Implicit surfaces from samples: normals, outliers and spacing, MPU and partition-of-unity RBF fits."""
