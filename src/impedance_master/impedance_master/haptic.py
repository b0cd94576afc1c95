"""Simulated master haptic device: a DC motor on a capstan drive with a current loop and the
PID force loop of thesis Eq. 36, pushing against the operator's hand.

Sign convention (same as the slave's force): x is the insertion (m, + inserting); a positive
force at the hand resists insertion (the device pushes the hand back, -x).

Model (SI):
* motor force on the handle ``F_mot = (kt / r) i``; electrical ``L di/dt = V - R i + (ke/r) x'``
  (back-EMF of the capstan's rotation), voltage saturated to +-v_max, current to +-i_max;
* current loop: PI at the substep rate (``substeps`` per control period), anti-windup;
* force loop (Eq. 36), once per control period on the handle force sensor f_m:
  ``i_ref = kp e + kd de/dt + ki int e  (+ f_d r / kt feed-forward)``, e = f_d - f_m
  (the thesis writes e = f_m - f_d with the opposite current sign);
* handle: moving mass M (handle + reflected rotor inertia), Coulomb + viscous friction;
* the hand: RIGID (the handle follows the scripted trajectory; the force at the hand is
  ``M x'' + F_mot + friction``) or COMPLIANT (a spring-damper of stiffness hand_stiffness
  and damping hand_damping around the scripted trajectory drives the handle, which then
  moves under the net force).
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Optional

from catheter_common.checks import (check_declared, checked, finite, integer, nonneg, positive,
                                    seed as check_seed)


@dataclass(frozen=True)
class DeviceParams:
    """Parameters of the simulated haptic device (a small capstan-driven DC motor).

    moving_mass kg 0.15; coulomb_friction N 0.01; viscous_friction N s/m 0.05;
    kt N m/A 0.025 (ke V s/rad equal); radius m 0.0125 (force constant 2 N/A);
    resistance ohm 1.5; inductance H 6e-4 (electrical time constant 0.4 ms);
    v_max V 12; i_max A 2 (4 N peak); current loop kp_i V/A 3.8, ki_i V/(A s) 9400
    (about 1 kHz bandwidth); force loop (Eq. 36) kp A/N 0.2, ki A/(N s) 60, kd A s/N 0.0,
    feedforward True; force-sensor noise N 0.002; substeps 10 per control period.
    """

    moving_mass: float = checked(0.15, 'positive')
    coulomb_friction: float = checked(0.01, 'nonneg')
    viscous_friction: float = checked(0.05, 'nonneg')
    kt: float = checked(0.025, 'positive')
    radius: float = checked(0.0125, 'positive')
    resistance: float = checked(1.5, 'positive')
    inductance: float = checked(6e-4, 'positive')
    v_max: float = checked(12.0, 'positive')
    i_max: float = checked(2.0, 'positive')
    kp_i: float = checked(3.8, 'nonneg')
    ki_i: float = checked(9400.0, 'nonneg')
    kp: float = checked(0.35, 'nonneg')
    ki: float = checked(150.0, 'nonneg')
    kd: float = checked(0.0, 'nonneg')
    feedforward: bool = True
    sensor_noise: float = checked(0.002, 'nonneg')
    substeps: int = 10

    def __post_init__(self):
        check_declared(self)
        integer('substeps', self.substeps, 1, 1000)


class DeviceSample(float):
    """One control period of the device. Its value (it IS a float) is the force at the
    operator's hand in N; attributes: f_hand N (the same), x handle position m, xd m/s,
    xdd m/s^2, current A (motor), f_measured N (handle force sensor reading)."""

    __slots__ = ('f_hand', 'x', 'xd', 'xdd', 'current', 'f_measured')

    def __new__(cls, f_hand: float, x: float, xd: float, xdd: float, current: float,
                f_measured: float):
        obj = super().__new__(cls, f_hand)
        obj.f_hand = float(f_hand)
        obj.x, obj.xd, obj.xdd = x, xd, xdd
        obj.current, obj.f_measured = current, f_measured
        return obj

    def __repr__(self) -> str:
        return (f'DeviceSample(f_hand={self.f_hand:.6g}, x={self.x:.6g}, xd={self.xd:.6g}, '
                f'xdd={self.xdd:.6g}, current={self.current:.6g}, '
                f'f_measured={self.f_measured:.6g})')


class HapticDevice:
    """DC-motor haptic device with current loop and PID force loop (thesis Eq. 36).

    Args:
        params: DeviceParams (defaults if None).
        dt: s, control period (1 kHz).
        hand_stiffness: N/m; None = rigid hand (handle follows the script exactly).
        hand_damping: N s/m (compliant hand only; 15 N s/m, a firm grasp: with much less the
            force loop rings against the hand-handle resonance).
        seed: force-sensor noise seed.
    """

    def __init__(self, params: Optional[DeviceParams] = None, dt: float = 1e-3,
                 hand_stiffness: Optional[float] = None, hand_damping: float = 15.0,
                 seed: Optional[int] = 0):
        self.p = params or DeviceParams()
        if not isinstance(self.p, DeviceParams):
            raise ValueError(f'params must be a DeviceParams, got {type(params).__name__}')
        self.dt = positive('dt', dt)
        self.hand_stiffness = None if hand_stiffness is None else positive(
            'hand_stiffness', hand_stiffness)
        self.hand_damping = nonneg('hand_damping', hand_damping)
        self.seed = check_seed('seed', seed)
        self.reset()

    def reset(self, x: float = 0.0) -> None:
        self.i = 0.0
        self._int_i = 0.0
        self._int_f = 0.0
        self._e_last = 0.0
        self._f_meas = 0.0
        self.x = finite('x', x)
        self.xd = 0.0
        self.xdd = 0.0
        self._started = False
        self._hand_last = (self.x, 0.0)
        self._rng = random.Random(self.seed)

    def _friction(self, v: float) -> float:
        p = self.p
        return p.coulomb_friction * math.tanh(v / 1e-3) + p.viscous_friction * v

    def step(self, f_desired: float, x_hand, xd_hand: Optional[float] = None,
             xdd_hand: float = 0.0) -> DeviceSample:
        """Advance one control period tracking f_desired (N) against the hand.

        x_hand, xd_hand, xdd_hand: the scripted hand trajectory at this period (m, m/s, m/s^2);
        the hand state may also be given as one sequence (x, xd[, xdd]) in x_hand.
        Returns the DeviceSample at the end of the period: a float, the force at the hand (N),
        with the device state as attributes.
        """
        if xd_hand is None:
            try:
                hand = [float(v) for v in x_hand]
            except TypeError:
                raise ValueError('xd_hand must be given, or x_hand must be a sequence '
                                 f'(x, xd[, xdd]); got {x_hand!r}') from None
            if len(hand) not in (2, 3):
                raise ValueError(f'x_hand as a sequence must be (x, xd[, xdd]), got {x_hand!r}')
            x_hand, xd_hand = hand[0], hand[1]
            xdd_hand = hand[2] if len(hand) == 3 else 0.0
        fd = finite('f_desired', f_desired)
        xh = finite('x_hand', x_hand)
        vh = finite('xd_hand', xd_hand)
        ah = finite('xdd_hand', xdd_hand)
        p = self.p
        if not self._started:
            self.x, self.xd = xh, vh
            self._hand_last = (xh, vh)
            self._started = True
        kf = p.kt / p.radius
        # --- force loop, Eq. 36 (on the last measured handle force) ---
        e = fd - self._f_meas
        de = (e - self._e_last) / self.dt
        self._e_last = e
        i_ref = p.kp * e + p.kd * de + self._int_f
        if p.feedforward:
            i_ref += fd / kf
        if i_ref > p.i_max or i_ref < -p.i_max:
            i_ref = max(-p.i_max, min(p.i_max, i_ref))  # saturated: no integration (anti-windup)
        else:
            self._int_f += p.ki * e * self.dt
        # --- current loop and mechanics, substeps ---
        n = p.substeps
        h = self.dt / n
        decay = math.exp(-p.resistance * h / p.inductance)
        gain = (1.0 - decay) / p.resistance
        rigid = self.hand_stiffness is None
        x, v = self.x, self.xd
        f_hand = 0.0
        a = 0.0
        # the substeps on local names (the same operations in the same order as
        # `_friction` and the attributes they stand for: identical numbers, no attribute
        # lookups inside the 1 kHz loop)
        xd0 = self.xd
        i, int_i = self.i, self._int_i
        kp_i, ki_i, v_max, i_max = p.kp_i, p.ki_i, p.v_max, p.i_max
        kt, radius, mass = p.kt, p.radius, p.moving_mass
        coulomb, viscous, tanh = p.coulomb_friction, p.viscous_friction, math.tanh
        ks, kd_hand = self.hand_stiffness, self.hand_damping
        # the compliant hand's target moves through the period from the last period's script
        # sample to this one (as the rigid handle's velocity does): held at the period's end
        # instead, the spring lagged the handle by half a period of travel on average, and
        # the force read at the period's end was low by ks v dt / 2 (3 mN at 20 mm/s)
        xh0, vh0 = self._hand_last
        self._hand_last = (xh, vh)
        for s in range(n):
            frac = (s + 1) / n          # how far through the period this substep ends
            ei = i_ref - i
            volt = kp_i * ei + int_i
            if volt > v_max or volt < -v_max:
                volt = max(-v_max, min(v_max, volt))
            else:
                int_i += ki_i * ei * h
            if rigid:
                v = xd0 + (vh - xd0) * frac
            emf = kt * v / radius
            # exact step of L di/dt = V - R i + emf for a held voltage
            i = i * decay + (volt + emf) * gain
            if i > i_max:
                i = i_max
            elif i < -i_max:
                i = -i_max
            f_mot = kf * i
            if rigid:
                a = ah
                f_hand = mass * a + f_mot + (coulomb * tanh(v / 1e-3) + viscous * v)
            else:
                f_hand = (ks * (xh0 + (xh - xh0) * frac - x)
                          + kd_hand * (vh0 + (vh - vh0) * frac - v))
                a = (f_hand - f_mot - (coulomb * tanh(v / 1e-3) + viscous * v)) / mass
                v += a * h
                x += v * h
        self.i, self._int_i = i, int_i
        if rigid:
            x, v = xh, vh
        self.x, self.xd, self.xdd = x, v, a
        noise = self._rng.gauss(0.0, p.sensor_noise) if p.sensor_noise > 0 else 0.0
        self._f_meas = f_hand + noise
        return DeviceSample(f_hand, x, v, a, self.i, self._f_meas)
