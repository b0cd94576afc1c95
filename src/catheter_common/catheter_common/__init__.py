"""Shared ROS 2 plumbing for the catheter packages.

`catheter_common.topics` holds topic names, frames and QoS profiles;
`catheter_common.ros_node` holds the node runner, diagnostics and parameter helpers.
"""
