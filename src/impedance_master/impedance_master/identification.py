"""Slave-side identification of the catheter-vessel environment: the public entry point.

* `SlidingWindowIdentifier` (`sliding_window.py`): the thesis method (Eqs. 29-34) done well,
  a linear model over a sliding window, O(1) per sample.
* `HistoryIdentifier` (`history.py`, settings in `history_params.HistoryParams`): the
  project's default, a nonlinear table model learned from the whole history.
* `make_identifier(window, rate)`: the default (what impedance_identifier_node runs).

Both have ``update(x, xd, xdd, f) -> Impedance | None`` (None before enough data).
Pure Python + numpy; time is implicit in the sample rate; deterministic.
"""
from __future__ import annotations

from impedance_master.history import HistoryIdentifier
from impedance_master.history_params import HistoryParams
from impedance_master.sliding_window import SlidingWindowIdentifier


def make_identifier(window: float = 1.0, rate: float = 1000.0, **kwargs) -> HistoryIdentifier:
    """The project's default identifier (what impedance_identifier_node runs); keyword
    arguments: `HistoryParams` fields or ``params=HistoryParams(...)``."""
    return HistoryIdentifier(window=window, rate=rate, **kwargs)


__all__ = ['SlidingWindowIdentifier', 'HistoryIdentifier', 'HistoryParams', 'make_identifier']
