"""Finite Arc Method (FAM) forward model of a planar catheter, a reference Kirchhoff rod
solver, and the fam_solver_node.

Public API (DESIGN section 5)::

    from fam_solver import Catheter, Loads, solve_fam, solve_fam_batch, solve_elastica
    cat = Catheter(length=0.04, ei=7.5e-4)                      # m, N m^2
    shape = solve_fam(cat, Loads(tip_force=(0.0, 0.5)), n_arcs=12)
    shape.tip, shape.tip_angle, shape.centerline(50), shape.arc_angles, shape.arc_lengths
    solve_fam(cat, loads, n_arcs=12, arc_model='exact', spacing='graded')   # circular arcs
    # defaults: arc_model='clothoid' (fourth order), spacing='uniform'

    shape.status            # Status.CONVERGED / NOT_CONVERGED / UNSTABLE / SNAP_THROUGH

The algorithm modules (everything but ``fam_solver_node``, see ``fam`` for the map) are free
of rclpy; ``fam_solver_node`` is the thin ROS 2 node.
"""
from .model import BatchShape, Catheter, Loads, Shape
from .fam import (ARC_MODELS, DEFAULT_ARC_MODEL, DEFAULT_SPACING, SPACINGS, Status,
                  graded_fractions, solve_fam, solve_fam_batch)
from .elastica import solve_elastica
from .arcs import bezier_lambda

__all__ = ['Catheter', 'Loads', 'Shape', 'BatchShape', 'solve_fam', 'solve_fam_batch',
           'solve_elastica', 'bezier_lambda', 'ARC_MODELS', 'DEFAULT_ARC_MODEL', 'SPACINGS',
           'DEFAULT_SPACING', 'graded_fractions', 'Status']
