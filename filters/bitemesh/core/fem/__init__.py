"""Finite elements on the mesh: P1 assembly, the solver check, the myocardial fibres, the elastic template."""
