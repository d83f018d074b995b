"""Exact timers: ``after()``, ``idle()`` and delayed events decided on integer nanoseconds.

Stock sismic compares ``time - seconds >= entry_time`` in binary floating point, so a timer can
miss its own deadline: entered at 7.7, ``after(2)`` is false at 9.7 (``9.7 - 2`` is
``7.699999999999999``), and a runner that wakes the chart at the deadline finds nothing to do.
Here every time and delay stands for the decimal it is written as (:mod:`rasm.times`) and the
comparison is made on exact nanoseconds: a timer holds at its deadline whatever the entry time.
That is the only departure from stock sismic's semantics; what is not a finite number (a delay
of ``inf``, ``nan``, a string) is compared as stock does, with its result or its error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

from sismic.code import PythonEvaluator
from sismic.model import Event, Transition

from rasm.times import FAST, from_nanoseconds, nanoseconds

__all__ = ["ExactTimerEvaluator", "deadline", "elapsed"]

_FAST_NS = int(FAST) * 10**9  # below 2**21 s, every time to the ns is a float of its own


def elapsed(since: Any, now: Any, seconds: Any) -> bool:
    """Whether ``seconds`` have passed from ``since`` to ``now`` (``now - seconds >= since``,
    exactly)."""
    gap = now - seconds - since  # stock's arithmetic first (and its error, for a string)
    # Binary arithmetic decides unless the gap is within its error (a few nanoseconds, plus
    # 2**-52 of the times' size): the exact comparison (a function call per time) settles that.
    slack = 2e-9 + 4e-16 * (abs(now) + abs(seconds) + abs(since))
    if gap > slack:
        return True
    if gap < -slack:
        return False
    start, current, delay = nanoseconds(since), nanoseconds(now), nanoseconds(seconds)
    if start is None or current is None or delay is None:
        return now - seconds >= since  # stock's arithmetic, and its errors
    return current - delay >= start


def deadline(since: Any, seconds: Any) -> Any:
    """When ``seconds`` after ``since`` is: the time at which :func:`elapsed` turns true.

    An int plus an int is that int, and no delay (0) leaves ``since`` as it is; otherwise it is
    the float nearest the exact sum, or the next float up where that one reads as earlier
    (beyond 2**23 s, where floats are coarser than a nanosecond): a runner that wakes the chart
    at this time finds the timer holding.
    """
    if seconds.__class__ is int:
        if seconds == 0:  # the usual case: an event queued without a delay
            return since
        if since.__class__ is int:
            return since + seconds
    if (
        since.__class__ is float
        and (seconds.__class__ is float or seconds.__class__ is int)
        and -FAST < since < FAST
        and -FAST < seconds < FAST
    ):  # nanoseconds() written out for the usual case
        return (round(since * 1e9) + round(seconds * 1e9)) / 1e9
    start, delay = nanoseconds(since), nanoseconds(seconds)
    if start is None or delay is None:
        return since + seconds  # stock's arithmetic, and its errors
    due = start + delay
    if -_FAST_NS < due < _FAST_NS:
        return due / 1e9  # both exact: one rounding, and floats are finer than a ns here
    time = from_nanoseconds(due)
    if math.isfinite(time) and nanoseconds(time) < due:
        time = math.nextafter(time, math.inf)
    return time


class ExactTimerEvaluator(PythonEvaluator):
    """sismic's Python evaluator with exact ``after()`` and ``idle()`` (:func:`elapsed`), in
    guards and in contracts alike; everything else is stock's."""

    def _timers(self, state: str) -> dict[str, Callable[[Any], bool]]:
        interp = self._interpreter
        return {
            "after": lambda seconds: elapsed(interp._entry_time[state], interp.time, seconds),
            "idle": lambda seconds: elapsed(interp._idle_time[state], interp.time, seconds),
        }

    def evaluate_guard(self, transition: Transition, event: Event | None = None) -> bool:
        context = self._timers(transition.source)
        context["event"] = event
        return self._evaluate_code(getattr(transition, "guard", None), additional_context=context)

    def evaluate_invariants(self, obj: Any, event: Event | None = None) -> Iterator[str]:
        return self._unsatisfied(obj, "invariants", event)

    def evaluate_postconditions(self, obj: Any, event: Event | None = None) -> Iterator[str]:
        return self._unsatisfied(obj, "postconditions", event)

    def _unsatisfied(self, obj: Any, kind: str, event: Event | None) -> Iterator[str]:
        """Stock's invariants and postconditions: the conditions of ``kind`` that fail, with
        the names stock exposes to them."""
        state = obj.source if isinstance(obj, Transition) else obj.name
        interp = self._interpreter
        context = {
            "__old__": self._memory.get(id(obj), None),
            **self._timers(state),
            "received": lambda name: name == getattr(event, "name", None),
            "sent": lambda name: name in [e.name for e in interp._sent_events],
            "event": event,
        }
        return filter(
            lambda condition: not self._evaluate_code(condition, additional_context=context),
            getattr(obj, kind, []),
        )
