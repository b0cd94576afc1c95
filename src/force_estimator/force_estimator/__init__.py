"""Tip force estimation from Bezier control points: learned models (SVR, MLP) trained on
simulation, and FAM inversion.

>>> from force_estimator import load_estimator, FamInverseEstimator
>>> est = load_estimator("blazer-svr")     # or "blazer-mlp", or a path to a .npz model
>>> est.predict(control_points)            # (4, 3) m -> (2,) N; (B, 4, 3) -> (B, 2)
>>> f, inside = est.predict(control_points, return_flags=True)   # training-envelope flag

Modules: `models` (numpy forward passes, pickle-free files, envelope), `training`
(scikit-learn fitting), `dataset` (learning-from-simulation data sets), `train` (the command
that rebuilds the shipped models), `fam_inverse` (FamInverseEstimator), and the ROS node
`force_estimator_node`. No module here except the node imports rclpy.
"""
from force_estimator.fam_inverse import FamInverseEstimator, FamInverseResult
from force_estimator.models import (SHIPPED_MODELS, ForceModel, control_points_to_features,
                                    load_estimator, load_model)

__all__ = ['load_estimator', 'load_model', 'ForceModel', 'FamInverseEstimator',
           'FamInverseResult', 'control_points_to_features', 'SHIPPED_MODELS']
