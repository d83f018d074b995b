"""The adaptation trace (SPEC §4): every record of the loop, as JSON lines.

Records are written in time order with ``time`` first. The same records feed the Trustworthiness
Checker's online monitors, so what ``rasm check`` says about a trace file is what the monitors saw
live.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from rasm.loop import LOOP_KEYS  # moved to rasm.loop; imported from here by rasm.platform

__all__ = ["LOOP_KEYS", "TraceWriter", "round_time"]

# json.dumps(..., separators=...) makes a new encoder per call: one for every line instead
_encode = json.JSONEncoder(separators=(", ", ": ")).encode


def jsonable(value: Any) -> Any:
    """``value`` as a trace line holds it: a non-finite float (not JSON) becomes None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# below 2**52 a float's floor and the halves between integers are floats: see round_time
_FAST_ROUND_BELOW = 2.0**52


def round_time(time: float) -> Any:
    """``round(time, 9)``: a record's time to the nanosecond, as a trace holds it.

    round() converts to decimal and back (thousands of instructions, and every record is
    rounded). For a positive float ``t`` whose product ``p = t * 1e9`` (the exact ``P = t *
    10**9`` rounded to a float) is below 2**52, with ``k`` its floor: rounding to a float is
    monotonic and ``k``, ``k + 1/2`` and ``k + 1`` are floats, so ``p < k + 1/2`` means ``P``
    is within 1/2 of ``k``, and ``p > k + 1/2`` within 1/2 of ``k + 1``. That integer over
    1e9 (both exact, the division correctly rounded) is the float nearest it times 10**-9:
    what round() gives. Anything else (``p`` exactly ``k + 1/2``, a time not a float, 0,
    negative, large or not finite) is round()'s.
    """
    if type(time) is float:
        scaled = time * 1e9
        if 0.0 < scaled < _FAST_ROUND_BELOW:
            whole = scaled // 1.0  # exact, as is the fraction
            fraction = scaled - whole
            if fraction < 0.5:
                return whole / 1e9
            if fraction > 0.5:
                return (whole + 1.0) / 1e9
    return round(time, 9)


def _line(time: float, record: dict[str, Any]) -> str:
    """The record's JSON line: ``time`` first (to the nanosecond), a non-finite float null."""
    line = {"time": round_time(time)}
    for key, value in record.items():
        line[key] = jsonable(value)
    return _encode(line) + "\n"


class TraceWriter:
    """Collects loop records; writes them to ``path`` (if any) and hands them to ``observers``.

    Each line is handed to the operating system as it is written (a flush per record, about 2
    µs), so a process killed at any moment leaves every record it emitted in the file.

    With ``max_bytes``, the file is rotated by size: when a line would take it past
    ``max_bytes``, ``trace.jsonl`` becomes ``trace.1.jsonl`` (an older ``trace.1.jsonl``
    becomes ``trace.2.jsonl``, and so on), the oldest beyond ``keep`` is deleted, and a fresh
    ``trace.jsonl`` goes on. A trace left by an earlier run is rotated away the same way on
    opening. The files take at most about ``(keep + 1) * max_bytes``; a record is never split.
    """

    # slots for what each record reads, ``__dict__`` for the rest (as rasm.platform.block.Block)
    __slots__ = (
        "path", "_out", "_owned", "observers", "records", "last_time", "__dict__", "__weakref__",
    )

    def __init__(
        self, path: str | Path | None = None, *, max_bytes: int | None = None, keep: int = 4
    ) -> None:
        if max_bytes is not None and max_bytes <= 0:
            raise ValueError(f"max_bytes must be positive, not {max_bytes}")
        if keep < 0:
            raise ValueError(f"keep must be 0 or more, not {keep}")
        self.path = Path(path) if path is not None and str(path) != "-" else None
        self.max_bytes = max_bytes if self.path is not None else None
        self.keep = keep
        self.rotations = 0
        self._size = 0  # bytes in the current file (lines are ASCII: json escapes the rest)
        self._out: TextIO | None = None
        self._owned = self.path is not None
        if str(path) == "-":
            import sys

            self._out = sys.stdout
        elif self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.max_bytes is not None and self.path.exists() and self.path.stat().st_size:
                self._shift()  # an earlier run's trace is kept, not overwritten
            self._out = open(self.path, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self.observers: list[Callable[[float, dict[str, Any]], Any]] = []
        self.records = 0
        self.last_time = -math.inf

    def rotated(self, n: int) -> Path:
        """The path of the ``n``-th older file: ``trace.jsonl`` → ``trace.<n>.jsonl``."""
        assert self.path is not None
        return self.path.with_name(f"{self.path.stem}.{n}{self.path.suffix}")

    def emit(self, time: float, record: dict[str, Any]) -> None:
        last = self.last_time
        if last > time:  # never back in time (SPEC §4); max(time, last) without the call
            time = last
        self.last_time = time
        self.records += 1
        out = self._out
        if out is not None:
            line = _line(time, record)
            if self.max_bytes is not None:
                if self._size and self._size + len(line) > self.max_bytes:
                    self._rotate()
                    out = self._out
                self._size += len(line)
            out.write(line)
            out.flush()
        for observer in self.observers:
            observer(time, record)

    def _shift(self) -> None:
        """Move ``trace.jsonl`` to ``trace.1.jsonl``, each older one a place up, and delete
        what falls beyond ``keep``."""
        for n in range(self.keep, 0, -1):
            older = self.path if n == 1 else self.rotated(n - 1)
            if older.exists():
                older.replace(self.rotated(n))
        self.path.unlink(missing_ok=True)  # keep 0: the full file is dropped

    def _rotate(self) -> None:
        assert self._out is not None
        self._out.close()
        self._shift()
        self._out = open(self.path, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self._size = 0
        self.rotations += 1

    def flush(self) -> None:
        if self._out is not None:
            self._out.flush()

    def close(self) -> None:
        if self._out is not None and self._owned:
            self._out.close()
        self._out = None
