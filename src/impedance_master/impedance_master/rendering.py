"""Master-side force rendering: impedance matching (IMA, thesis Eq. 35) and direct force
reflection (DFR, the thesis's baseline).

`ImaRenderer` evaluates the latest environment model on the master's LOCAL trajectory, so
the feedback neither waits for nor stalls with the network. A new model never kicks the
operator's hand: at a switch the difference between the old and the new model at the
current state is taken up by a bumpless-transfer term that decays with `blend_time`
(the rendered force is continuous across switches), and optionally the output slews at
most `max_rate` N/s. The renderer owns the Dahl friction state of table models, driven by the
master's own position. Invalid models (identifier warming up or without a good estimate)
are ignored: the previous model stays in use.

`DfrRenderer` returns the last received slave force (held during outages).

Both clamp their output to +-`limit` N (default 2 N, the clinical insertion range).
"""
from __future__ import annotations

import math
from typing import Optional

from catheter_common.checks import finite, nonneg, positive
from impedance_master.impedance import FrictionState, Impedance


class _Clamp:
    def __init__(self, limit: float):
        self.limit = positive('limit', limit)
        self.n_clamped = 0

    def __call__(self, f: float) -> float:
        lim = self.limit
        if f > lim:
            self.n_clamped += 1
            return lim
        if f < -lim:
            self.n_clamped += 1
            return -lim
        return f


class _LimitedOutput:
    """The safe output limit both renderers share: `limit` (N) and `n_clamped`."""

    _clamp: _Clamp

    @property
    def limit(self) -> float:
        return self._clamp.limit

    @property
    def n_clamped(self) -> int:
        return self._clamp.n_clamped


class ImaRenderer(_LimitedOutput):
    """Impedance-matching renderer: f_d from the latest model and the local trajectory.

    Args:
        limit: N, safe output limit (|f_d| <= limit).
        blend_time: s, time constant of the bumpless transfer at a model switch (0: jump).
        max_rate: N/s, slew-rate limit of the output (> 0; default inf: none; the nodes use
            20 N/s as a safety net).
    Every switch is bumpless, the first one too: it blends in from the force rendered before
    (0 N), so the first model does not step the operator's hand either.
        dt: s, the call period (1 kHz loop), used by blending and slew limiting.
        passivity: add the time-domain passivity controller (TDPA, Ryu & Hannaford): the
            observer E = sum f x' dt is the energy the operator has put into the rendered
            environment; when it would go negative (the model, e.g. a negative damping or a
            switch, returned more than it received), a damping alpha x' with
            alpha = -E / (dt x'^2) (at most max_damping N s/m) dissipates the excess.
    Attributes: `model` (in use), `n_switches`, `n_ignored` (invalid models), `n_clamped`,
    `energy` (J, observer), `n_passivity` (steps with added damping).
    """

    def __init__(self, limit: float = 2.0, blend_time: float = 0.05,
                 max_rate: float = math.inf, dt: float = 1e-3, passivity: bool = False,
                 max_damping: float = 50.0):
        self._clamp = _Clamp(limit)
        self.blend_time = nonneg('blend_time', blend_time)
        try:
            self.max_rate = float(max_rate)
        except (TypeError, ValueError):
            raise ValueError(f'max_rate must be a number > 0 (inf: none), got {max_rate!r}') \
                from None
        if math.isnan(self.max_rate) or self.max_rate <= 0.0:
            raise ValueError(f'max_rate must be > 0 (inf: none), got {max_rate!r}')
        self.dt = positive('dt', dt)
        self.model: Optional[Impedance] = None
        self._pending: Optional[Impedance] = None
        self._bump = 0.0
        self._decay = math.exp(-dt / blend_time) if blend_time > 0 else 0.0
        self._last_out = 0.0
        self._state: Optional[FrictionState] = None
        self._z = (0.0, 0.0)
        self._x = None
        self._xd = 0.0
        self._xdd = 0.0
        self.n_switches = 0
        self.n_ignored = 0
        self.passivity = bool(passivity)
        self.max_damping = positive('max_damping', max_damping)
        self.energy = 0.0
        self.n_passivity = 0

    def set_impedance(self, imp: Impedance) -> bool:
        """Offer a new model; returns True if it will be used (valid), False if ignored."""
        if not isinstance(imp, Impedance):
            raise ValueError(f'imp must be an Impedance, got {type(imp).__name__}')
        if not imp.valid:
            self.n_ignored += 1
            return False
        self._pending = imp
        return True

    def _switch(self, x: float, xd: float, xdd: float) -> None:
        new = self._pending
        self._pending = None
        if new is self.model:
            return
        if new.S is not None and (self._state is None or (self._state.sigma, self._state.v_s,
                                                          self._state.beta)
                                  != (new.sigma, new.v_s, new.beta)):
            st = new.make_state()
            z0 = self._z if self._state is not None else st.steady(xd)
            st.reset(x, *z0)
            self._state = st
            self._z = z0
        if self.blend_time > 0.0:
            z = self._z if self._state is not None else None
            new_f = new.force(x, xd, xdd, z if new.S is not None else None)
            if self.model is not None:
                old_f = self.model.force(x, xd, xdd, z if self.model.S is not None else None)
            else:
                old_f = self._last_out      # the first model: blend in from what was rendered (0 N)
            self._bump += old_f - new_f
        self.model = new
        self.n_switches += 1

    def desired_force(self, x: float, xd: float, xdd: float) -> float:
        """Desired force in N at the hand for the master state (x m, xd m/s, xdd m/s^2).

        0 until a valid model has arrived. Call once per control period `dt`.
        """
        x = finite('x', x)
        xd = finite('xd', xd)
        xdd = finite('xdd', xdd)
        if self._state is not None:
            self._z = self._state.update(x, xd)
        if self._pending is not None:
            self._switch(x, xd, xdd)
        if self.model is None:
            f = 0.0
        else:
            m = self.model
            f = m.force(x, xd, xdd, self._z if m.S is not None else None) + self._bump
            self._bump *= self._decay
        last = self._last_out
        if last is not None and math.isfinite(self.max_rate):
            step = self.max_rate * self.dt
            if f > last + step:
                f = last + step
            elif f < last - step:
                f = last - step
        if self.passivity:
            f = self._passivity(f, xd)
        f = self._clamp(f)
        self._last_out = f
        if self.passivity:
            self.energy += f * xd * self.dt
        return f

    def _passivity(self, f: float, xd: float) -> float:
        e = self.energy + f * xd * self.dt
        if e < 0.0 and xd * xd > 1e-12:
            alpha = min(-e / (self.dt * xd * xd), self.max_damping)
            self.n_passivity += 1
            return f + alpha * xd
        return f


class DfrRenderer(_LimitedOutput):
    """Direct force reflection: the desired force is the last force received from the slave.

    Args: limit: N, safe output limit.
    """

    def __init__(self, limit: float = 2.0):
        self._clamp = _Clamp(limit)
        self._f = 0.0
        self.n_updates = 0

    def set_force(self, f: float) -> None:
        """New slave force in N (finite)."""
        self._f = finite('f', f)
        self.n_updates += 1

    def desired_force(self, *_state) -> float:
        """Desired force in N (the state arguments, if any, are ignored)."""
        return self._clamp(self._f)
