"""Tip force estimation from Bezier control points: learned models (SVR, MLP) trained on
simulation, and FAM inversion; every estimate with its uncertainty, domain status and method.

>>> from force_estimator import load_estimator, FamInverseEstimator, make_estimator
>>> est = load_estimator("blazer-svr")     # or "blazer-mlp", or a path to a .npz model
>>> est.predict(control_points)            # (4, 3) m -> (2,) N; (B, 4, 3) -> (B, 2) (bounded)
>>> f, inside = est.predict(control_points, return_flags=True)   # training-envelope flag
>>> e = make_estimator("svr").estimate(control_points)   # ForceEstimate, FAM fallback
>>> e.force, e.covariance, e.status, e.method, e.domain_distance, e.normal

Modules: `estimate` (ForceEstimate, statuses), `inputs` (input checks), `models` (numpy
forward passes, pickle-free files, envelope, validation on load), `domain` (training
domain check), `uncertainty` (covariance from the FAM Jacobian), `fam_inverse`
(FamInverseEstimator), `hybrid` (learned model + FAM fallback, make_estimator), `training`
(scikit-learn fitting), `dataset` (learning-from-simulation data sets through the camera
styles), `train` (the command that rebuilds the shipped models), and the ROS node
`force_estimator_node`. No module here except the node imports rclpy.
"""
from force_estimator.estimate import NORMAL, STATUSES, ForceEstimate
from force_estimator.fam_inverse import FamInverseEstimator, FamInverseResult
from force_estimator.hybrid import HybridEstimator, make_estimator
from force_estimator.inputs import control_points_to_features
from force_estimator.models import SHIPPED_MODELS, ForceModel, load_estimator, load_model

__all__ = ['load_estimator', 'load_model', 'ForceModel', 'FamInverseEstimator',
           'FamInverseResult', 'control_points_to_features', 'SHIPPED_MODELS',
           'ForceEstimate', 'STATUSES', 'NORMAL', 'HybridEstimator', 'make_estimator']
