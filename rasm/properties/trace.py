"""Reading traces (SPEC §4): JSONL, one record a line, ``time`` plus the signals it updates.

Every malformed record is reported with its line (and the column of the offending key): not a
JSON object, no numeric ``time``, a time going back, a value of the wrong type for a signal
the properties read. Blank lines are skipped; the others are records 0, 1, 2, …

A time is a JSON number of seconds. Where its float loses digits (epoch seconds with nine
decimals), it is read again from the line's text as a :class:`~rasm.properties.times.Seconds`: a
float that carries the exact nanoseconds the monitors compare.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

from rasm.errors import Location, Misfit, SourceError, SourceErrors, read_utf8
from rasm.jsontext import JsonProblem, parse_json
from rasm.properties.times import FAST, Seconds, nanoseconds
from rasm.values import fit, wanted

__all__ = ["read_trace", "parse_trace", "MAX_REPORTED"]

MAX_REPORTED = 50  # a broken file is reported by its first problems, not a million lines
def _fits(value: object, kind: str) -> bool:
    try:
        fit(value, kind, int_as_float=False)  # nan and the infinities are numbers here
    except Misfit:
        return False
    return True


_TIME_TEXT = re.compile(r'"time"\s*:\s*(-?[0-9][0-9.eE+-]*)')


def _exact_time(line: str, time: float) -> float:
    """``time``, a float too large for its decimals to survive, read again from ``line``."""
    # JSON keeps the last of repeated keys; a "time" key of a nested object reads differently
    for text in reversed(_TIME_TEXT.findall(line)):
        try:
            exact = Seconds(text)
        except ValueError:
            continue
        if exact == time:
            return exact
    return time


def _column(line: str, key: str) -> int:
    position = line.find(json.dumps(key))
    return position + 1 if position >= 0 else 1


def parse_trace(
    lines: Iterable[str],
    signals: Mapping[str, str] | None = None,
    *,
    source: str = "<trace>",
) -> list[tuple[float, dict]]:
    """Parse trace lines into ``(time, values)`` records, checking them against ``signals``.

    ``signals`` maps signal names to float | int | bool | str | any (a monitor's
    ``spec.signals``); other keys are kept unchecked. Raises :class:`SourceErrors` listing every
    malformed record (at most :data:`MAX_REPORTED`).
    """
    signals = signals or {}
    records: list[tuple[float, dict]] = []
    errors: list[SourceError] = []
    hidden = 0
    last_time = -math.inf
    last_ns = -math.inf  # compared exactly, as the monitors do

    def fail(message: str, number: int, col: int = 1) -> None:
        nonlocal hidden
        if len(errors) < MAX_REPORTED:
            errors.append(SourceError(message, Location(source, number, col)))
        else:
            hidden += 1

    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            record = parse_json(line.rstrip("\r\n"))
        except JsonProblem as exc:
            fail(exc.message, number, exc.column)
            continue
        if not isinstance(record, dict):
            fail(f"a record must be a JSON object, not {type(record).__name__}", number)
            continue
        time = record.pop("time", None)
        if time is None:
            fail("record without 'time' (seconds, a number)", number)
            continue
        if time.__class__ not in (int, float) or time != time:
            fail(f"'time' must be a number, not {json.dumps(time)}", number, _column(line, "time"))
            continue
        if time.__class__ is float and math.isinf(time):
            fail(f"'time' must be finite, not {json.dumps(time)}", number, _column(line, "time"))
            continue
        if time.__class__ is float and not -FAST < time < FAST:
            time = _exact_time(line, time)
        ns = nanoseconds(time)
        if ns < last_ns:
            fail(
                f"time {time} goes back in time (the previous record has {last_time})",
                number,
                _column(line, "time"),
            )
            continue
        bad = False
        for key, value in record.items():
            kind = signals.get(key)
            if kind is not None and not _fits(value, kind):
                fail(
                    f"{key!r} must be {wanted(kind)}, not {json.dumps(value)}",
                    number,
                    _column(line, key),
                )
                bad = True
        if bad:
            continue
        last_time, last_ns = time, ns
        records.append((time, record))
    if errors:
        if hidden:
            errors.append(SourceError(
                f"… and {hidden} more malformed records (fix the ones above first)",
                Location(source),
            ))
        raise SourceErrors(errors)
    return records


def read_trace(path: str | Path, signals: Mapping[str, str] | None = None) -> list:
    """Read a JSONL trace file; see :func:`parse_trace`."""
    path = Path(path)
    try:
        with path.open(encoding="utf-8") as handle:
            return parse_trace(handle, signals, source=str(path))
    except UnicodeDecodeError:
        read_utf8(path)  # read whole, to name the line and column of the first bad byte
        raise
