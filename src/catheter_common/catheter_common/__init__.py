"""Shared ROS 2 plumbing for the catheter packages (see README.md).

Pure Python (importable anywhere): `topics` (names and frames), `checks` (argument checks).
Node plumbing: `qos`, `params` (parameters applied at run time or refused), `diagnostics`
(counters and leveled conditions), `images`, `ros_node` (`run_node`), `ros_testing`.
"""
