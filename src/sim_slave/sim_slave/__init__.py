"""Simulated patient side: insertion robot, vessel interaction, force sensor, camera stream, UDP-like link."""
