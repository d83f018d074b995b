"""Logging and Tracking: the platform's log records, to the console, a file or the bus."""

from __future__ import annotations

import contextlib
import io
import logging
import sys
from collections import Counter
from collections.abc import Callable
from typing import Any

from rasm.errors import PlatformError
from rasm.losses import WriteFailure, WriteGuard, describe_error
from rasm.platform.block import Block

__all__ = ["LoggingAndTracking"]


class _BusHandler(logging.Handler):
    """Publishes log records on a bus topic; never recurses into itself."""

    def __init__(self, publish: Callable[[dict[str, Any]], Any]) -> None:
        super().__init__()
        self.publish = publish
        self._busy = False

    def emit(self, record: logging.LogRecord) -> None:
        if self._busy:
            return
        self._busy = True
        try:
            self.publish(
                {
                    "level": record.levelname,
                    "logger": record.name,
                    "message": record.getMessage(),
                    "created": record.created,
                }
            )
        except Exception:  # a broken bus must not break logging
            pass
        finally:
            self._busy = False


class _FileHandler(logging.FileHandler):
    """A log file written line by line (nothing buffered to fail later): a line the disk
    refuses is counted in ``guard`` (the first one logged, on the other sinks), never printed
    as a "--- Logging error ---" traceback."""

    def __init__(self, path: str, guard: WriteGuard) -> None:
        self.guard = guard
        try:
            super().__init__(path, encoding="utf-8")
        except OSError as exc:
            raise PlatformError(f"opening the log file {path} failed: {describe_error(exc)}"
                                ) from None

    def _open(self):  # noqa: ANN202 - logging's own hook
        raw = open(self.baseFilename, "ab", buffering=0)  # noqa: SIM115 - closed by close()
        return io.TextIOWrapper(raw, encoding="utf-8", write_through=True)

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 - logging's name
        exc = sys.exc_info()[1]
        if not isinstance(exc, OSError):
            super().handleError(record)
            return
        self.guard.fail("writing", exc, lost=1, consequence="the run goes on; the lines that "
                        "cannot be written are counted (the run summary shows them)")

    def close(self) -> None:
        with contextlib.suppress(OSError):
            super().close()


class _CountingHandler(logging.Handler):
    """Counts records per severity (handlers see what child loggers propagate; filters don't)."""

    def __init__(self, counts: Counter[str]) -> None:
        super().__init__()
        self.counts = counts

    def emit(self, record: logging.LogRecord) -> None:
        self.counts[record.levelname] += 1


class LoggingAndTracking(Block):
    """Logging and Tracking (lt): severities and sinks on the standard ``logging`` module.

    ``sinks`` are ``console`` (standard error), ``file:PATH`` and ``bus:TOPIC`` (each record
    published as ``{"level", "logger", "message", "created"}``). The sinks are attached to the
    ``rasm`` logger while the block is initialised, so every platform module's records reach them.
    """

    chart_name = "logging_and_tracking"
    short_name = "lt"

    def __init__(
        self,
        *,
        level: int = logging.WARNING,
        sinks: tuple[str, ...] = ("console",),
        publish: Callable[[str, dict[str, Any]], Any] | None = None,
        logger: str = "rasm",
        **kw: Any,
    ) -> None:
        self.logger = logging.getLogger(logger)
        self.level = level
        self.sinks = tuple(sinks)
        self.publish = publish
        self.handlers: list[logging.Handler] = []
        self.counts: Counter[str] = Counter()
        self.guards: list[WriteGuard] = []  # one per log file
        super().__init__(**kw)

    @property
    def failures(self) -> list[WriteFailure]:
        """The log files that refused writes."""
        return [g.failure for g in self.guards if g.failure is not None]

    def on_configuration(self) -> None:
        for sink in self.sinks:
            kind, _, target = sink.partition(":")
            if kind not in ("console", "file", "bus") or (kind != "console" and not target):
                raise ValueError(f"unknown log sink {sink!r} (console, file:PATH or bus:TOPIC)")

    def on_initialization(self) -> None:
        fmt = logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s")
        for sink in self.sinks:
            kind, _, target = sink.partition(":")
            if kind == "console":
                handler: logging.Handler = logging.StreamHandler()
            elif kind == "file":
                guard = WriteGuard("log file", target, unit="lines", logger=self.logger)
                self.guards.append(guard)
                handler = _FileHandler(target, guard)
            else:
                publish = self.publish
                if publish is None:
                    continue
                handler = _BusHandler(lambda payload, t=target, p=publish: p(t, payload))
            handler.setLevel(self.level)
            handler.setFormatter(fmt)
            self.logger.addHandler(handler)
            self.handlers.append(handler)
        counter = _CountingHandler(self.counts)
        counter.setLevel(self.level)
        self.logger.addHandler(counter)
        self.handlers.append(counter)
        self.logger.setLevel(min(self.level, self.logger.level or self.level))

    def on_termination(self) -> None:
        for handler in self.handlers:
            self.logger.removeHandler(handler)
            handler.close()
        self.handlers.clear()

    def is_enabled(self, severity: int = logging.INFO) -> bool:
        return self.mode == "initialized" and severity >= self.level

    def log(self, severity: int, message: str, *args: Any, exc_info: Any = None) -> None:
        if self.is_enabled(severity):
            self.logger.log(severity, message, *args, exc_info=exc_info)
