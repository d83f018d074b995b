"""The adaptation trace: JSON lines, one record a line, ``time`` first, then what it updates.

Written by :class:`TraceWriter` (``rasm run --trace``; :func:`rasm.trace_mcap.open_trace_writer`
picks it or the MCAP writer), read whole by :func:`read_trace` and :func:`parse_trace`
(``rasm report``) or record by record by :func:`read_records` and :func:`parse_records`
(``rasm check``), held in memory as a :class:`rasm.testing.Trace` of records (``run_app``). A
record in memory is what :func:`trace_line` gives: the record as it reads back from its line, so
a trace in memory and the same trace read from its file are equal.

A line holds ``time`` rounded to the nanosecond and every other value as JSON has it; NaN at
the top level (a sensor's failed reading) is written as ``null``, and the infinities as
``Infinity`` and ``-Infinity`` (Python's JSON dialect, which the reader takes back): they are
values, a property's robustness among them (SPEC §12: ±inf where only booleans decide).

Reading reports every malformed record at its line (and the column of the offending key): not
a JSON object, no numeric ``time``, a time going back, a value of the wrong type for a signal
the properties read. Blank lines are skipped; the others are records 0, 1, 2, … A time is a
JSON number of seconds; where its float loses digits (epoch seconds with nine decimals) it is
read again from the line's text as a :class:`~rasm.properties.times.Seconds`: a float that
carries the exact nanoseconds the monitors compare.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from itertools import islice
from json.scanner import make_scanner
from pathlib import Path
from typing import Any, BinaryIO

from rasm.errors import (
    Location,
    Misfit,
    PlatformError,
    RasmError,
    SourceError,
    SourceErrors,
    read_utf8,
)
from rasm.jsontext import JsonProblem, parse_json
from rasm.losses import WriteFailure, WriteGuard, describe_error
from rasm.properties.times import FAST, Seconds, format_seconds, nanoseconds
from rasm.values import fit, wanted

_log = logging.getLogger("rasm.trace")

__all__ = [
    "MAX_REPORTED", "MalformedTrace", "TraceWriter", "format_line", "parse_records",
    "parse_trace", "read_records", "read_trace", "scan_records", "trace_line",
]


# ----------------------------------------------------------------------------- the line


def _jsonable(value: Any) -> Any:
    """``value`` as a line holds it at the top level: NaN (no reading) is None; the
    infinities stay (a robustness of ±inf is a value, and reads back as one)."""
    if isinstance(value, float) and value != value:
        return None
    return value


def format_line(time: float, record: Mapping[str, Any]) -> str:
    """The record's JSON line (without its newline): ``time`` first, to the nanosecond."""
    line = {"time": round(time, 9)}
    for key, value in record.items():
        line[key] = _jsonable(value)
    return json.dumps(line)


def trace_line(time: float, record: Mapping[str, Any]) -> dict[str, Any]:
    """The record as it reads back from its line: what a :class:`Trace` holds."""
    return json.loads(format_line(time, record))


# ----------------------------------------------------------------------------- writing


class TraceWriter:
    """Writes loop records to ``path`` (if any; ``"-"`` is standard output) and hands them to
    ``observers``.

    Records never go back in time: one emitted with a time before the last's is written at the
    last's. Each line is handed to the operating system as it is written (one ``write`` per
    record, nothing buffered), so a process killed at any moment leaves every record it
    emitted in the file.

    A write that fails (a full disk, a read-only file system, a closed pipe) never reaches the
    caller: the observers (the Trustworthiness Checker among them) still get every record, the
    file is cut back to its last whole record and written no more, the failure is logged once
    with the file and the operation, and :attr:`failure` counts the records left out (the run
    summary shows it, and the run exits 1). A file that cannot be created raises
    :class:`~rasm.errors.PlatformError` naming it, before the run starts.

    With ``max_bytes``, the file is rotated by size: when a line would take it past
    ``max_bytes``, ``trace.jsonl`` becomes ``trace.1.jsonl`` (an older ``trace.1.jsonl``
    becomes ``trace.2.jsonl``, and so on), the oldest beyond ``keep`` is deleted, and a fresh
    ``trace.jsonl`` goes on. A trace left by an earlier run is rotated away the same way on
    opening. The files take at most about ``(keep + 1) * max_bytes``; a record is never split.
    """

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
        self._size = 0  # bytes in the current file: it is cut back here when a write fails
        self._file: BinaryIO | None = None  # unbuffered: one write per record
        self._stdout = str(path) == "-"
        self.guard = WriteGuard(
            "trace", str(self.path) if self.path is not None else "on standard output",
            logger=_log,
        )
        if self.path is not None:
            self._create()
        self.observers: list[Callable[[float, dict[str, Any]], Any]] = []
        self.records = 0
        self.last_time = -math.inf

    @property
    def failure(self) -> WriteFailure | None:
        """The writes that failed, and the records left out of the file (None: none)."""
        return self.guard.failure

    def _create(self) -> None:
        assert self.path is not None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.max_bytes is not None and self.path.exists() and self.path.stat().st_size:
                self._shift()  # an earlier run's trace is kept, not overwritten
            self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close()
            self._size = 0
            self._begin()
        except OSError as exc:
            if self._file is not None:
                self._file.close()
                self._file = None
            raise PlatformError(
                f"creating the trace {self.path} failed: {describe_error(exc)}"
            ) from None

    def _begin(self) -> None:
        """Write what a fresh file starts with (nothing: JSONL has no header)."""

    def _encode(self, time: float, record: dict[str, Any]) -> bytes:
        """One record as the file holds it."""
        return (format_line(time, record) + "\n").encode("ascii")  # json escapes the rest

    def _put(self, data: bytes) -> None:
        """Hand ``data`` to the operating system (raises OSError)."""
        assert self._file is not None
        view = memoryview(data)
        while view:
            view = view[self._file.write(view) or 0:]
        self._size += len(data)

    def rotated(self, n: int) -> Path:
        """The path of the ``n``-th older file: ``trace.jsonl`` → ``trace.<n>.jsonl``."""
        assert self.path is not None
        return self.path.with_name(f"{self.path.stem}.{n}{self.path.suffix}")

    def emit(self, time: float, record: dict[str, Any]) -> None:
        """Write one record and hand it to the observers."""
        time = max(time, self.last_time)
        self.last_time = time
        self.records += 1
        if self._file is not None or self._stdout:
            self._write(time, record)
        elif self.guard.failure is not None:
            self.guard.lose()
        for observer in self.observers:
            observer(time, record)

    def _write(self, time: float, record: dict[str, Any]) -> None:
        data = self._encode(time, record)
        operation = "writing"
        try:
            if self._stdout:
                sys.stdout.write(data.decode("ascii"))
                sys.stdout.flush()
                return
            if self.max_bytes is not None and self._size and self._size + len(data) > (
                self.max_bytes
            ):
                operation = "rotating"
                self._rotate()
                operation = "writing"
            self._put(data)
        except OSError as exc:
            self._stop(operation, exc, time)

    def _stop(self, operation: str, exc: OSError, time: float) -> None:
        """A write failed: log it once, cut the file back to its last whole record, and write
        no more (the records from here on are counted as lost)."""
        self.guard.fail(
            operation, exc, lost=1, time=time,
            consequence="the run goes on; this record and every later one are left out of the "
            "file (the run summary counts them)",
        )
        file, self._file, self._stdout = self._file, None, False
        if file is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(file.fileno(), self._size)
            with contextlib.suppress(OSError):
                file.close()

    def _shift(self) -> None:
        """Move ``trace.jsonl`` to ``trace.1.jsonl``, each older one a place up, and delete
        what falls beyond ``keep``."""
        assert self.path is not None
        for n in range(self.keep, 0, -1):
            older = self.path if n == 1 else self.rotated(n - 1)
            if older.exists():
                older.replace(self.rotated(n))
        self.path.unlink(missing_ok=True)  # keep 0: the full file is dropped

    def _rotate(self) -> None:
        assert self._file is not None and self.path is not None
        self._file.close()
        self._file = None
        self._shift()
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close()
        self._size = 0
        self.rotations += 1

    def flush(self) -> None:
        """Nothing is held back in a file; standard output is flushed."""
        if self._stdout:
            try:
                sys.stdout.flush()
            except OSError as exc:
                self._stop("writing", exc, self.last_time)

    def close(self) -> None:
        """Finish and close the file; a failure is counted, never raised."""
        file = self._file
        if file is None:
            return
        try:
            self._finish()
        except OSError as exc:
            self.guard.fail("closing", exc, consequence="its last part may be missing")
        finally:
            self._file = None
            try:
                file.close()
            except OSError as exc:
                self.guard.fail("closing", exc, consequence="its last part may be missing")

    def _finish(self) -> None:
        """Write what a file ends with (nothing: JSONL has no footer)."""


# ----------------------------------------------------------------------------- reading

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


# the classes a JSON value that fits each kind has (``fit`` decides for any other class)
_FITTING = {
    "float": (int, float),  # an int for a float is kept exact; NaN is a number here
    "int": (int,),
    "bool": (bool,),
    "str": (str,),
    "any": (bool, int, float, str),
}
# json.loads without its per-call wrapping: the C scanner JSONDecoder itself calls
_scan = make_scanner(json.JSONDecoder())


def _decode_plain(line: str) -> object:
    """The JSON value of a line that is one JSON text and its line break, else None (then the
    full parser reads the line and says what is wrong with it)."""
    try:
        value, end = _scan(line, 0)
    except (StopIteration, ValueError, RecursionError):
        return None
    return None if line[end:].strip(" \t\n\r") else value


_BLANK = object()  # what _decode gives for a blank line


def _decode(line: str) -> object:
    """A trace line's JSON value, or _BLANK; raises JsonProblem where it is no JSON text."""
    record = _decode_plain(line)
    if record is None:
        if not line.strip():
            return _BLANK
        record = parse_json(line.rstrip("\r\n"))
    return record


def parse_records(
    lines: Iterable[str],
    signals: Mapping[str, str] | None = None,
    *,
    source: str = "<trace>",
) -> Iterator[tuple[float, dict]]:
    """Parse trace lines into ``(time, values)`` records one by one, checking them against
    ``signals``: what :func:`parse_trace` gives, without holding the trace.

    ``signals`` maps signal names to float | int | bool | str | any (a monitor's
    ``spec.signals``); other keys are kept unchecked. A malformed record is not given; once the
    lines are read, :class:`SourceErrors` lists every one (at most :data:`MAX_REPORTED`).
    """
    signals = signals or {}
    fitting = {name: _FITTING.get(kind, ()) for name, kind in signals.items()}
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
        try:
            record = _decode(line)
        except JsonProblem as exc:
            fail(exc.message, number, exc.column)
            continue
        if record is _BLANK:
            continue
        if not isinstance(record, dict):
            fail(f"a record must be a JSON object, not {type(record).__name__}", number)
            continue
        time = record.pop("time", None)
        if isinstance(time, float) and -FAST < time < FAST:
            ns = round(time * 1e9)  # nanoseconds(time), written out for the common case
        else:
            if time is None:
                fail("record without 'time' (seconds, a number)", number)
                continue
            if isinstance(time, bool) or not isinstance(time, int | float) or time != time:
                fail(f"'time' must be a number, not {json.dumps(time)}", number,
                     _column(line, "time"))
                continue
            if isinstance(time, float) and math.isinf(time):
                fail(f"'time' must be finite, not {json.dumps(time)}", number,
                     _column(line, "time"))
                continue
            if isinstance(time, float):
                time = _exact_time(line, time)
            ns = nanoseconds(time)
        if ns < last_ns:
            fail(
                f"time {format_seconds(time)} goes back in time (the previous record has "
                f"{format_seconds(last_time)})",
                number,
                _column(line, "time"),
            )
            continue
        bad = False
        for key, value in record.items():
            classes = fitting.get(key)
            # the class test settles what JSON gives; fit() judges anything else
            if classes is not None and value.__class__ not in classes and not _fits(
                value, signals[key]
            ):
                fail(
                    f"{key!r} must be {wanted(signals[key])}, not {json.dumps(value)}",
                    number,
                    _column(line, key),
                )
                bad = True
        if bad:
            continue
        last_time, last_ns = time, ns
        yield time, record
    if errors:
        if hidden:
            errors.append(SourceError(
                f"… and {hidden} more malformed records (fix the ones above first)",
                Location(source),
            ))
        raise SourceErrors(errors)


class MalformedTrace(RasmError):
    """A line :func:`scan_records` cannot pass on: :func:`parse_records` names every such line."""


def scan_records(
    lines: Iterable[str],
    unchecked: Mapping[str, str] | None = None,
    *,
    source: str = "<trace>",
) -> Iterator[tuple[float, dict]]:
    """The records of trace lines, for a monitor that checks them as it goes: the fast reader
    of ``rasm check``.

    Each line is decoded and its ``time`` taken out (read exactly from the text where a float
    loses digits); the values of ``unchecked`` signals (name -> kind) are checked. The rest of
    :func:`parse_records`' checks, the time's type and order and the values of the signals a
    property reads, are the monitor's, which refuses such a record (``Monitor.feed`` raises).
    A line that is not a JSON object with a ``time``, or a value that does not fit, raises
    :class:`MalformedTrace`. Either way, :func:`parse_records` then reports every malformed
    line of the trace.

    The lines are decoded :data:`SCANNED` at a time, as one JSON array (one call of the
    decoder, not one per line); a block that is not plain (a blank or malformed line, a time
    whose float loses digits, a signal to check) is read line by line.
    """
    lines = iter(lines)
    number = 0  # the lines before this block
    while block := list(islice(lines, SCANNED)):
        records = None if unchecked else _scan_block(block)
        if records is None:
            records = _scan_lines(block, unchecked or {}, source, number)
        number += len(block)
        yield from records


SCANNED = 4096  # lines decoded at once by scan_records

# Between two lines of a block, the string "\x00": JSON can write it only as this text, so a
# block whose text holds it exactly where it was put, and whose array has it at every other
# place, had each line decode to one value. (A line cut short would take the next line into
# its value, and the line "1, 2" gives two values: with plain commas between the lines, the
# two together would still give one value per line.)
_SEPARATOR = '"\\u0000"'


def _scan_block(block: list[str]) -> list[tuple[float, dict]] | None:
    """The records of ``block``, a list of lines, if every line is one JSON object with a
    ``time`` whose float is exact (below FAST); else None."""
    text = "[" + f",{_SEPARATOR},".join(block) + "]"
    between = len(block) - 1
    if text.count(_SEPARATOR) != between:
        return None
    try:
        values, end = _scan(text, 0)
    except (StopIteration, ValueError, RecursionError):
        return None
    if end != len(text) or len(values) != 2 * between + 1 or (
        values[1::2].count("\x00") != between
    ):
        return None
    records = values[::2]
    try:
        # (a dict's pop takes a key; a list's raises TypeError, other values have none)
        times = [record.pop("time") for record in records]
        plain = -FAST < min(times) and max(times) < FAST  # (NaN first: False)
    except (KeyError, AttributeError, TypeError):
        return None
    return list(zip(times, records, strict=True)) if plain else None


def _scan_lines(block: list[str], unchecked: Mapping[str, str], source: str,
                before: int) -> Iterator[tuple[float, dict]]:
    """:func:`scan_records` of a block line by line (``before``: the lines before it)."""
    for number, line in enumerate(block, start=before + 1):
        try:
            record = _decode(line)
        except JsonProblem:
            raise MalformedTrace(f"{source}:{number}: not a JSON text") from None
        if record is _BLANK:
            continue
        if not isinstance(record, dict):
            raise MalformedTrace(f"{source}:{number}: not a JSON object")
        time = record.pop("time", None)
        if time is None:
            raise MalformedTrace(f"{source}:{number}: no 'time'")
        if isinstance(time, float) and not -FAST < time < FAST and math.isfinite(time):
            time = _exact_time(line, time)
        if unchecked:
            for key, kind in unchecked.items():
                if key in record and not _fits(record[key], kind):
                    raise MalformedTrace(f"{source}:{number}: {key!r} does not fit")
        yield time, record


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
    return list(parse_records(lines, signals, source=source))


def read_records(
    path: str | Path, signals: Mapping[str, str] | None = None
) -> Iterator[tuple[float, dict]]:
    """Read a JSONL trace file record by record; see :func:`parse_records`."""
    path = Path(path)
    try:
        with path.open(encoding="utf-8") as handle:
            yield from parse_records(handle, signals, source=str(path))
    except UnicodeDecodeError:
        read_utf8(path)  # read whole, to name the line and column of the first bad byte
        raise


def read_trace(path: str | Path, signals: Mapping[str, str] | None = None) -> list:
    """Read a JSONL trace file; see :func:`parse_trace`."""
    return list(read_records(path, signals))
