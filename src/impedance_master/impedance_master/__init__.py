"""Impedance-matching force feedback: slave-side identification, master-side IMA and DFR
rendering, simulated haptic device and operator (thesis Ch. 4, DESIGN section 5).

Public API::

    from impedance_master import SlidingWindowIdentifier, make_identifier, ImaRenderer, DfrRenderer
    ident = SlidingWindowIdentifier(window=1.0, rate=1000.0)   # the thesis method, done well
    best = make_identifier(window=1.0, rate=1000.0)             # the project's default
    imp = ident.update(x, xd, xdd, f)       # Impedance or None before the window fills
    ima = ImaRenderer(); ima.set_impedance(imp); ima.desired_force(x, xd, xdd)
    dfr = DfrRenderer(); dfr.set_force(f); dfr.desired_force()

The core modules never import rclpy; the *_node modules are the ROS 2 nodes.
"""
from impedance_master.haptic import DeviceParams, DeviceSample, HapticDevice
from impedance_master.identification import (HistoryIdentifier, HistoryParams,
                                             SlidingWindowIdentifier, make_identifier)
from impedance_master.impedance import FrictionState, Impedance
from impedance_master.envelope import DEFAULT_ENVELOPE, ModelEnvelope
from impedance_master.operator import (OPERATORS, OperatorTrajectory, experiment_trajectory,
                                       make_operator)
from impedance_master.state_file import StateFile
from impedance_master.rendering import DfrRenderer, ImaRenderer

__all__ = ['SlidingWindowIdentifier', 'HistoryIdentifier', 'HistoryParams', 'make_identifier',
           'Impedance', 'FrictionState', 'ImaRenderer', 'DfrRenderer', 'HapticDevice',
           'DeviceParams', 'DeviceSample', 'OperatorTrajectory', 'experiment_trajectory',
           'make_operator',
           'OPERATORS', 'ModelEnvelope', 'DEFAULT_ENVELOPE', 'StateFile']
