"""Clocks: simulated time for simulation and tests, monotonic time for live runs.

sismic's ``UtcClock`` reads ``time.time()``, which jumps when the system clock is set; a live loop
measures durations and deadlines, so it uses :class:`MonotonicClock` instead.
"""

from __future__ import annotations

import time as _time

from sismic.clock import Clock, SimulatedClock

__all__ = ["Clock", "MonotonicClock", "SimulatedClock"]


class MonotonicClock(Clock):
    """Seconds since the clock was created, from ``time.monotonic()`` (never goes back)."""

    def __init__(self, start: float = 0.0) -> None:
        self._origin = _time.monotonic() - start

    @property
    def time(self) -> float:
        return _time.monotonic() - self._origin

    def __repr__(self) -> str:
        return f"MonotonicClock[{self.time:.6f}]"
