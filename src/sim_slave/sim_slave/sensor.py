"""The slave's insertion force sensor (an ATI Mini-type load cell under the phantom in the thesis):
Gaussian noise, an optional constant bias, optional quantisation and saturation."""
from __future__ import annotations

import math
import random
from typing import Optional

from catheter_common.checks import finite, nonneg, positive_or_inf, seed as check_seed


class ForceSensor:
    """Measured force = quantise(clip(true force + bias + N(0, noise_std^2))).

    Args:
        noise_std: N, standard deviation of the white Gaussian noise (default 0.01 N, the
            order of an ATI Mini40's resolution and of the thesis's force ripple).
        seed: int >= 0 or None, for the noise generator (deterministic for a seed).
        bias: N, constant offset added to every reading (default 0).
        resolution: N, quantisation step (0 = none).
        saturation: N, readings are clipped to [-saturation, saturation] (inf = none).
    """

    def __init__(self, noise_std: float = 0.01, seed: Optional[int] = 0, bias: float = 0.0,
                 resolution: float = 0.0, saturation: float = math.inf):
        self.noise_std = nonneg('noise_std', noise_std)
        self.bias = finite('bias', bias)
        self.resolution = nonneg('resolution', resolution)
        self.saturation = positive_or_inf('saturation', saturation)
        self.seed = check_seed('seed', seed)
        self.reset()

    def reset(self) -> None:
        """Restart the noise sequence from the seed."""
        self._rng = random.Random(self.seed)

    def measure(self, f: float) -> float:
        """One reading in N of the true force `f` in N."""
        f = finite('f', f)
        y = f + self.bias
        if self.noise_std > 0.0:
            y += self._rng.gauss(0.0, self.noise_std)
        if y > self.saturation:
            y = self.saturation
        elif y < -self.saturation:
            y = -self.saturation
        if self.resolution > 0.0:
            y = round(y / self.resolution) * self.resolution
        return y
