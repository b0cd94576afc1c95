"""Impedance-matching force feedback: slave-side identification, master-side IMA and DFR rendering, simulated haptic device and operator."""
