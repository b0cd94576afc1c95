"""The vessel a sim node simulates, from its parameters (pure Python, no rclpy: the nodes and
the offline analysis, which builds the same vessel as the reference, use this one function).

    spec = vessel_from_params({'vessel': 'stiff_wall', 'vessel.wall_depth': 0.03})
    spec.build(seed), spec.sensor(seed + 1)

``vessel`` names one of `sim_slave.vessels` (phantom, smooth_coulomb, stribeck_kv, stenosis,
soft, stiff_wall; default phantom). The ``vessel.<field>`` parameters (VesselParams fields)
and ``sensor.noise_std`` are declared with the PHANTOM's values as defaults; a value that
differs from that default overrides the named vessel's own, the others leave it as it is
(so ``vessel: stiff_wall`` alone gives the whole stiff_wall vessel).
"""
from __future__ import annotations

from dataclasses import fields
from typing import Mapping

from sim_slave.vessel import VesselParams
from sim_slave.vessels import VESSELS, vessel_names, vessel_spec

#: the names a `vessel` parameter accepts (family names, then aliases)
VESSEL_CHOICES = vessel_names()
#: the vessel of the project's default runs
DEFAULT_VESSEL = VESSELS[0]
#: N, the default of sensor.noise_std: the phantom's sensor noise
PHANTOM_NOISE = vessel_spec(DEFAULT_VESSEL).noise_std


def vessel_from_params(values: Mapping[str, object]):
    """The `sim_slave.vessels.VesselSpec` of a node's parameter values ('vessel', the
    'vessel.<field>' and 'sensor.noise_std' entries; missing ones take their defaults).
    ValueError naming an unknown vessel or a bad value."""
    name = values.get('vessel', DEFAULT_VESSEL)
    phantom = VesselParams()
    over = {}
    for f in fields(VesselParams):
        key = 'vessel.' + f.name
        if key in values and float(values[key]) != float(getattr(phantom, f.name)):
            over[f.name] = float(values[key])
    noise = values.get('sensor.noise_std', PHANTOM_NOISE)
    if float(noise) != PHANTOM_NOISE:
        over['noise_std'] = float(noise)
    return vessel_spec(name, **over)


__all__ = ['VESSEL_CHOICES', 'DEFAULT_VESSEL', 'PHANTOM_NOISE', 'vessel_from_params']
