"""Clocks: simulated time for simulation and tests, monotonic time for live runs.

sismic's ``UtcClock`` reads ``time.time()``, which jumps when the system clock is set; a live loop
measures durations and deadlines, so it uses :class:`MonotonicClock` instead. The simulated clock
is sismic's, read more cheaply (:class:`SimulatedClock`).
"""

from __future__ import annotations

import time as _time

from sismic import clock as _sismic_clock
from sismic.clock import Clock

__all__ = ["Clock", "MonotonicClock", "SimulatedClock"]


class MonotonicClock(Clock):
    """Seconds from ``time.monotonic()``, reading ``start`` when started (never goes back).

    With ``running=False`` the clock stands still at ``start`` until :meth:`start_at`, so a
    platform can be assembled (which takes time) before its timeline begins.
    """

    def __init__(self, start: float = 0.0, *, running: bool = True) -> None:
        self._start = start
        self._origin: float | None = _time.monotonic() - start if running else None

    @property
    def time(self) -> float:
        if self._origin is None:
            return self._start
        return _time.monotonic() - self._origin

    def start_at(self, start: float) -> None:
        """Start a standing clock at ``start`` (not before the time it stands at)."""
        if self._origin is not None:
            raise RuntimeError("the clock is already running")
        self._origin = _time.monotonic() - max(start, self._start)

    def __repr__(self) -> str:
        return f"MonotonicClock[{self.time:.6f}]"


class SimulatedClock(_sismic_clock.SimulatedClock):
    """sismic's ``SimulatedClock``, the same in every respect, with ``time`` read in one call.

    sismic computes ``time`` as ``_time + _elapsed``, two Python property calls; a simulated run
    reads the clock a few dozen times per loop iteration. This reads the same attributes and does
    the same arithmetic in one property.
    """

    @property
    def time(self) -> float:
        """Time value of this clock."""
        if self._play:
            return self._time + (_time.time() - self._base) * self._speed
        return self._time + 0  # (sismic adds an elapsed 0: the same number)

    @time.setter
    def time(self, new_time: float) -> None:
        _sismic_clock.SimulatedClock.time.fset(self, new_time)
