"""Failures that recur, logged without a flood: the first in full, then a count per interval.

A stage that raises at every iteration, or a probe that sends a wrong-type value with every
reading, would otherwise log the same traceback or warning many times a second. The loop logs
every such failure through one :class:`RepeatedLogs`::

    logs.log(_log, logging.ERROR, "plan stage failed: ZeroDivisionError: division by zero",
             "%s stage failed: %s\\n%s", stage, reason, traceback_text)

The first occurrence is logged as given (with its traceback). Later ones with the same text are
counted, and one line per ``interval`` says how many came: ``plan stage failed:
ZeroDivisionError: division by zero (56 more times in the last 10 s)``. :meth:`RepeatedLogs.flush`
logs what is still counted (at the end of a run) and :attr:`RepeatedLogs.totals` gives each
repeated failure's count, for the run summary.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rasm.times import format_seconds

__all__ = ["RepeatedLogs"]


@dataclass
class _Failure:
    logger: logging.Logger
    level: int
    unreported: int  # occurrences since the last line about it
    reported_at: float


class RepeatedLogs:
    """Logs each distinct failure once in full, then how often it recurred, per ``interval``.

    A failure is known by its text ``what``, which leaves out what changes between occurrences
    (a value, a duration). The interval is measured on ``clock``, wall-clock seconds by default:
    the point is to keep the log readable while it is written, whatever the run's clock. At most
    ``capacity`` distinct failures are remembered; beyond that the oldest is forgotten (its count
    logged first), so a failure whose text changes every time cannot grow memory without end.
    Safe to share between threads (a transport logs from its delivery thread).
    """

    def __init__(
        self,
        interval: float = 10.0,
        *,
        clock: Callable[[], float] = time.monotonic,
        capacity: int = 1000,
    ) -> None:
        self.interval = interval
        self.clock = clock
        self.capacity = capacity
        self._failures: dict[str, _Failure] = {}
        self._totals: dict[str, int] = {}  # the repeated ones, forgotten or not
        self._lock = threading.Lock()

    def log(
        self,
        logger: logging.Logger,
        level: int,
        what: str,
        message: str | None = None,
        *args: Any,
        exc_info: Any = None,
    ) -> bool:
        """Log failure ``what`` (as ``message % args`` the first time, if given); return
        whether this occurrence was logged in full."""
        with self._lock:
            return self._log(logger, level, what, message, args, exc_info)

    def _log(
        self,
        logger: logging.Logger,
        level: int,
        what: str,
        message: str | None,
        args: tuple[Any, ...],
        exc_info: Any,
    ) -> bool:
        now = self.clock()
        failure = self._failures.get(what)
        if failure is None:
            if len(self._failures) >= self.capacity:
                self._forget(next(iter(self._failures)), now)
            self._failures[what] = _Failure(logger, level, 0, now)
            if what in self._totals:  # it recurred before it was forgotten
                self._totals[what] += 1
            if message is None:
                logger.log(level, "%s", what, exc_info=exc_info)
            else:
                logger.log(level, message, *args, exc_info=exc_info)
            return True
        failure.unreported += 1
        self._totals[what] = self._totals.get(what, 1) + 1
        if now - failure.reported_at >= self.interval:
            self._report(what, failure, now)
        return False

    def _report(self, what: str, failure: _Failure, now: float) -> None:
        failure.logger.log(
            failure.level,
            "%s (%d more time%s in the last %s s)",
            what,
            failure.unreported,
            "" if failure.unreported == 1 else "s",
            format_seconds(round(now - failure.reported_at, 1)),
        )
        failure.unreported = 0
        failure.reported_at = now

    def _forget(self, what: str, now: float) -> None:
        failure = self._failures.pop(what)
        if failure.unreported:
            self._report(what, failure, now)

    def flush(self) -> None:
        """Log the count of every failure that recurred since its last line."""
        with self._lock:
            now = self.clock()
            for what, failure in self._failures.items():
                if failure.unreported:
                    self._report(what, failure, now)

    @property
    def totals(self) -> dict[str, int]:
        """Each failure that occurred more than once: how many times in all (while it was
        remembered: one forgotten for ``capacity`` starts afresh)."""
        with self._lock:
            return dict(self._totals)
