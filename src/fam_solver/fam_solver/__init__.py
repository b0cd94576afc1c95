"""Finite Arc Method (FAM) forward model of a planar catheter, a reference Kirchhoff rod solver, and the fam_solver_node."""
