"""The slave robot's insertion axis: a position-controlled linear stage.

A proportional position loop with velocity feed-forward (the command's velocity, from a
filtered difference of successive commands) sets the velocity set-point of a velocity-
controlled drive; the drive follows it with a first-order motor lag, limited in speed and
acceleration. The stroke is limited. This is the structure of the thesis's Phidgets DC-motor
stage (Hooshiar et al.), which tracks the received insertion command with < 5 % error.

The same class serves any single axis (the rotation axis in rad with other limits).
"""
from __future__ import annotations

import math
from typing import Optional, Tuple

from catheter_common.checks import finite, nonneg, number, positive, positive_or_inf


class SlaveRobot:
    """One position-controlled axis stepped at a fixed rate.

    Args:
        rate: Hz, control rate (one :meth:`step` per period 1/rate). Default 1000.
        kp: 1/s, position gain (velocity set-point per metre of error). Default 60: a ramp
            at 41.3 mm/s without feed-forward lags 0.7 mm (1.2 % of 56 mm).
        feedforward: -, gain on the command's velocity in [0, 1] (1 = full feed-forward).
        ff_time_constant: s, time constant of the low-pass on the command's velocity (0.01 s:
            smooths commands that arrive irregularly through a lossy link).
        motor_time_constant: s, first-order lag of the velocity drive (0.005 s; kp * tau =
            0.3 keeps the loop well damped, damping ratio 0.91).
        max_speed: axis units/s, speed limit (0.1 m/s, 2.4x the thesis's 41.3 mm/s).
        max_accel: axis units/s^2, acceleration limit (2 m/s^2).
        x_min, x_max: axis units, stroke; commands are clipped into it (default -0.02..0.20 m;
            +-inf allowed).
        x0: initial position (clipped into the stroke).
    """

    def __init__(self, rate: float = 1000.0, kp: float = 60.0, feedforward: float = 1.0,
                 ff_time_constant: float = 0.01, motor_time_constant: float = 0.005,
                 max_speed: float = 0.1, max_accel: float = 2.0,
                 x_min: float = -0.02, x_max: float = 0.20, x0: float = 0.0):
        self.rate = positive('rate', rate)
        self.dt = 1.0 / self.rate
        self.kp = positive('kp', kp)
        self.feedforward = nonneg('feedforward', feedforward)
        if self.feedforward > 1.0:
            raise ValueError(f'feedforward must be in [0, 1], got {feedforward!r}')
        self.ff_time_constant = nonneg('ff_time_constant', ff_time_constant)
        self.motor_time_constant = nonneg('motor_time_constant', motor_time_constant)
        self.max_speed = positive_or_inf('max_speed', max_speed)
        self.max_accel = positive_or_inf('max_accel', max_accel)
        lo, hi = number('x_min', x_min), number('x_max', x_max)
        if not lo < hi:
            raise ValueError(f'x_min must be < x_max, got x_min={x_min!r}, x_max={x_max!r}')
        self.x_min, self.x_max = lo, hi
        self.x0 = finite('x0', x0)
        self.reset()

    def reset(self, x0: Optional[float] = None) -> None:
        """Put the axis at rest at `x0` (default: the constructor's x0)."""
        if x0 is not None:
            self.x0 = finite('x0', x0)
        self.x = min(max(self.x0, self.x_min), self.x_max)
        self.xd = 0.0
        self.xdd = 0.0
        self._cmd_prev: Optional[float] = None
        self.command = self.x     # the last command, clipped to the stroke
        self._v_ff = 0.0
        self.steps = 0

    def step(self, x_cmd: float) -> Tuple[float, float, float]:
        """Advance one period towards the command `x_cmd` (axis units, clipped to the stroke).

        Returns (x, xd, xdd): position, velocity and acceleration after the step.
        """
        x_cmd = finite('x_cmd', x_cmd)
        x_cmd = min(max(x_cmd, self.x_min), self.x_max)
        dt = self.dt
        if self._cmd_prev is None:
            self._cmd_prev = x_cmd
        # command velocity for the feed-forward: a jump (after an outage) is not a velocity the
        # stage can follow, so the raw difference is clipped to the speed limit first
        raw = (x_cmd - self._cmd_prev) / dt
        raw = min(max(raw, -self.max_speed), self.max_speed)
        self._cmd_prev = x_cmd
        self.command = x_cmd
        self._v_ff += dt / (self.ff_time_constant + dt) * (raw - self._v_ff)
        # P on the position error, capped by the braking curve sqrt(2 a e) (with margin for the
        # motor lag) so that a large step decelerates within the acceleration limit
        e = x_cmd - self.x
        ae = abs(e)
        v_fb = self.kp * ae
        v_brake = 0.8 * math.sqrt(2.0 * self.max_accel * ae)
        v_sp = math.copysign(min(v_fb, v_brake), e) + self.feedforward * self._v_ff
        v_sp = min(max(v_sp, -self.max_speed), self.max_speed)
        a = (v_sp - self.xd) / (self.motor_time_constant + dt)
        a = min(max(a, -self.max_accel), self.max_accel)
        self.xd += a * dt
        x = self.x + self.xd * dt
        if x > self.x_max:
            x, self.xd, a = self.x_max, 0.0, 0.0
        elif x < self.x_min:
            x, self.xd, a = self.x_min, 0.0, 0.0
        self.x = x
        self.xdd = a
        self.steps += 1
        return self.x, self.xd, self.xdd
