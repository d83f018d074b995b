"""What a run or a recording lost: writes that failed, and recordings that are damaged.

A **write failure** is a file (or server) rasm writes while the loop runs — the trace, the
knowledge store, the timing file, a log file — that refused a write: a full disk, a read-only
file system, a server gone. Its writer keeps one :class:`WriteGuard`: the first failure is
logged once in full (what, the file, the operation, the system's reason), later ones are only
counted with what they cost, and the writer goes on without raising, so the loop, the
Trustworthiness Checker and the fallback never stop for it. The run summary lists each
:class:`WriteFailure` and the run exits 1.

A **damage** is a part of a recording that could not be read: an MCAP chunk whose bytes do
not check out, a record cut by the end of the file, SQLite pages that are malformed, messages
that do not decode. A :class:`Damage` says where it is, what was lost (bytes, messages, topics,
where known) and the time range it covers; a verdict that depended on it is not "satisfied".
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass, field

from rasm.times import format_nanoseconds, format_seconds

__all__ = [
    "Damage", "WriteFailure", "WriteGuard", "describe_error", "lost_messages",
]


def describe_error(exc: BaseException) -> str:
    """The system's reason for a failed write, without the file name the caller already says:
    ``No space left on device (errno 28)``."""
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror} (errno {exc.errno})" if exc.errno else exc.strerror
    sqlite3 = sys.modules.get("sqlite3")  # (its errors come only from it, loaded by then)
    if sqlite3 is not None and isinstance(exc, sqlite3.Error):
        return str(exc) or type(exc).__name__
    cause = exc.__cause__
    if cause is not None and cause is not exc:
        return describe_error(cause)  # a wrapper (KnowledgeError) around the system's reason
    return str(exc) or type(exc).__name__


def _count(n: int, unit: str) -> str:
    return f"{n:,} {unit if n != 1 else unit.rstrip('s')}"


@dataclass
class WriteFailure:
    """The failed writes of one target: the first one (``operation``, ``reason``, ``time``),
    how many writes failed in all, and how many items (``unit``) never reached the target."""

    what: str  # "trace", "knowledge", "timing", "log"
    target: str  # the file, or the server's URL
    operation: str  # of the first failure: "writing", "rotating", "committing", "closing"
    reason: str  # the system's reason: "No space left on device (errno 28)"
    unit: str = "records"
    time: float | None = None  # on the platform's timeline, where the writer knows it
    failures: int = 1
    lost: int = 0
    recovered: bool = False  # a later write succeeded (the target took writes again)

    def message(self, consequence: str = "") -> str:
        """The line logged at the first failure."""
        when = f" at t={format_seconds(self.time)} s" if self.time is not None else ""
        text = f"{self.what} {self.target}: {self.operation} failed{when}: {self.reason}"
        return f"{text}; {consequence}" if consequence else text

    def describe(self) -> str:
        """One line for the run summary."""
        when = f" from t={format_seconds(self.time)} s" if self.time is not None else ""
        times = "" if self.failures == 1 else f" ({self.failures:,} failed writes)"
        lost = f"; {_count(self.lost, self.unit)} lost" if self.lost else ""
        back = "; it took writes again later" if self.recovered else ""
        return (f"{self.what} {self.target}: {self.operation} failed{when}{times}: "
                f"{self.reason}{lost}{back}")


class WriteGuard:
    """The write failures of one target, reported once and then counted (see the module doc).

    ``fail`` records a failed write (logging the first in full through ``logger``), ``lose``
    counts items lost without a new attempt, ``succeeded`` notes a write that went through
    after failures. :attr:`failure` is None while every write succeeded.
    """

    def __init__(
        self, what: str, target: str, *, unit: str = "records", logger: logging.Logger
    ) -> None:
        self.what = what
        self.target = target
        self.unit = unit
        self.logger = logger
        self.failure: WriteFailure | None = None

    def fail(
        self,
        operation: str,
        exc: BaseException,
        *,
        lost: int = 0,
        time: float | None = None,
        consequence: str = "",
    ) -> WriteFailure:
        """Record a failed write that lost ``lost`` items; the first is logged (with
        ``consequence``: what happens now), the later ones only counted."""
        if self.failure is None:
            self.failure = WriteFailure(self.what, self.target, operation, describe_error(exc),
                                        self.unit, time, lost=lost)
            self.logger.error("%s", self.failure.message(consequence))
        else:
            self.failure.failures += 1
            self.failure.lost += lost
        return self.failure

    def lose(self, count: int = 1) -> None:
        """Count items lost after a failure without trying to write them."""
        if self.failure is not None:
            self.failure.lost += count

    def succeeded(self) -> None:
        """A write went through: after failures, say so once."""
        failure = self.failure
        if failure is not None and not failure.recovered:
            failure.recovered = True
            self.logger.warning("%s %s: writes go through again after %s", self.what,
                                self.target, _count(failure.failures, "failed writes"))


@dataclass(frozen=True)
class Damage:
    """A part of a recording that could not be read, and what was lost with it.

    ``where`` names the part (``chunk at byte 1,234``), ``reason`` what is wrong with it;
    ``lost_bytes`` and ``messages`` count what was lost (None: not known), ``start_ns`` and
    ``end_ns`` bound its log times (None: not known), ``topics`` names the topics it held
    (None: not known, so it may have held any).
    """

    file: str
    where: str
    reason: str
    lost_bytes: int | None = None
    messages: int | None = None
    start_ns: int | None = None
    end_ns: int | None = None
    topics: tuple[str, ...] | None = field(default=None)

    def concerns(self, topics: set[str] | frozenset[str]) -> bool:
        """Whether it may have held messages of ``topics``."""
        return self.topics is None or not topics.isdisjoint(self.topics)

    def describe(self) -> str:
        """``bag.mcap: chunk at byte 1,234 (65,536 bytes): its CRC does not match: 1,347
        messages on /odom lost, from t=1700000000.5 to 1700000013.9 s``."""
        size = f" ({_count(self.lost_bytes, 'bytes')})" if self.lost_bytes else ""
        lost = (_count(self.messages, "messages") if self.messages is not None
                else "an unknown number of messages")
        if self.topics:
            lost += f" on {', '.join(self.topics)}"
        text = f"{self.file}: {self.where}{size}: {self.reason}"
        if self.messages != 0:
            text += f": {lost} lost"
        if self.start_ns is not None and self.end_ns is not None:
            text += (f", from t={format_nanoseconds(self.start_ns)} "
                     f"to {format_nanoseconds(self.end_ns)} s")
        elif self.start_ns is not None:
            text += f", after t={format_nanoseconds(self.start_ns)} s"
        return text


def lost_messages(damages: list[Damage]) -> int | None:
    """The messages the damages lost in all; None when some count is not known."""
    counts = [d.messages for d in damages]
    return None if any(n is None for n in counts) else sum(n for n in counts if n is not None)
