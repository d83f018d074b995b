"""Clocks: simulated time for simulation and tests, monotonic time for live runs.

sismic's ``UtcClock`` reads ``time.time()``, which jumps when the system clock is set; a live loop
measures durations and deadlines, so it uses :class:`MonotonicClock` instead. Simulated time is
sismic's own :class:`~sismic.clock.SimulatedClock`.
"""

from __future__ import annotations

import time

from sismic.clock import Clock, SimulatedClock

__all__ = ["Clock", "MonotonicClock", "SimulatedClock"]


class MonotonicClock(Clock):
    """Seconds from ``time.monotonic()``, reading ``start`` when started (never goes back).

    With ``running=False`` the clock stands still at ``start`` until :meth:`start_at`, so a
    platform can be assembled (which takes time) before its timeline begins.
    """

    def __init__(self, start: float = 0.0, *, running: bool = True) -> None:
        self._start = start
        self._origin: float | None = time.monotonic() - start if running else None

    @property
    def time(self) -> float:
        if self._origin is None:
            return self._start
        return time.monotonic() - self._origin

    def start_at(self, start: float) -> None:
        """Start a standing clock at ``start`` (not before the time it stands at)."""
        if self._origin is not None:
            raise RuntimeError("the clock is already running")
        self._origin = time.monotonic() - max(start, self._start)

    def __repr__(self) -> str:
        return f"MonotonicClock[{self.time:.6f}]"
