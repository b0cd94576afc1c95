"""Simulated patient side: insertion robot, vessel interaction, force sensor, UDP-like link.

Core modules (no rclpy): :mod:`sim_slave.vessel`, :mod:`sim_slave.vessels` (the family),
:mod:`sim_slave.sensor`, :mod:`sim_slave.robot`, :mod:`sim_slave.link`, :mod:`sim_slave.slave`.
The node is :mod:`sim_slave.sim_slave_node`.
"""
from sim_slave.link import Link, LinkConfig, LinkStats
from sim_slave.robot import SlaveRobot
from sim_slave.sensor import ForceSensor
from sim_slave.slave import SlaveSample, SlaveSimulation
from sim_slave.vessel import VesselForce, VesselModel, VesselParams
from sim_slave.vessel_extras import VesselExtras
from sim_slave.vessels import VESSELS, VesselSpec, make_vessel, vessel_spec

__all__ = ['VesselParams', 'VesselModel', 'VesselForce', 'VesselExtras', 'VesselSpec',
           'VESSELS', 'make_vessel', 'vessel_spec', 'ForceSensor', 'SlaveRobot',
           'LinkConfig', 'Link', 'LinkStats', 'SlaveSimulation', 'SlaveSample']
