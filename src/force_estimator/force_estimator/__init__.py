"""Tip force estimation from Bezier control points: learned models (SVR, MLP) trained on simulation, and FAM inversion."""
