"""The grid I of the paper: the implicit function f sampled on a regular grid, and its compiled kernels."""
