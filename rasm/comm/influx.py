"""MAPLE-K timing to InfluxDB: the loop's records as line protocol.

:func:`record_to_points` maps a trace record to InfluxDB line-protocol lines:

- a stage record ``{"stage": "plan", "duration": d}`` at time ``t`` (the stage's start) gives
  ``maple_stage,stage=plan start=t,duration=d``;
- each adaptation event (``anomaly``, ``planned``, ``legitimate``, ``rejected``, ``trusted``,
  ``executed``) true on the record gives ``adaptation,event=…[,plan=…] value=true`` plus
  ``broken_rules`` and ``explanation`` as string fields where the record has them;
- the other keys (knowledge signals) give one ``knowledge`` point, one field per key.

:func:`verdict_to_point` gives ``verdict,property=… value=true|false[,index=i]``.

:class:`InfluxWriter` sends lines from a background thread in batches (``POST /write``), so the
loop never waits for the network: :meth:`~InfluxWriter.write` only appends to a bounded queue,
and what does not fit is dropped and counted. :meth:`~InfluxWriter.write_record` queues the
record itself: its lines are formatted with the rest of its batch, by the writer that fills the
batch (one loop, no second thread competing for the interpreter meanwhile), or by the writer's
thread for a batch that goes out unfilled at its deadline.
:meth:`InfluxWriter.to_file` writes the same lines to a file instead (``influx write``/``curl
--data-binary @FILE`` load it later).

Numbers are written as floats (``1`` as ``1.0``): InfluxDB refuses a field that changes type, and
a knowledge key may be ``0`` once and ``0.5`` later. NaN and infinities are left out.
"""

from __future__ import annotations

import contextlib
import functools
import http.client
import json
import logging
import math
import os
import threading
import time as _time
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import urlencode, urlsplit

from rasm.errors import CommError
from rasm.losses import WriteFailure, WriteGuard, describe_error

__all__ = [
    "ADAPTATION_EVENTS",
    "InfluxWriter",
    "WriterStats",
    "escape_key",
    "escape_measurement",
    "field_value",
    "query",
    "record_to_points",
    "verdict_to_point",
]

_log = logging.getLogger("rasm.comm.influx")

ADAPTATION_EVENTS = ("anomaly", "planned", "legitimate", "rejected", "trusted", "executed")
"""The trace's event keys that become ``adaptation`` points."""

_EVENTS = frozenset(ADAPTATION_EVENTS)
Entry = str | tuple[float, Mapping[str, Any]]
"""What the writer queues: a line, or a trace record whose lines it formats with its batch."""
_NOT_KNOWLEDGE = frozenset(
    ("time", "stage", "duration", "plan", "broken_rules", "explanation", *ADAPTATION_EVENTS)
)
_PRECISION = {"s": 1, "ms": 1_000, "u": 1_000_000, "ns": 1_000_000_000}


# --------------------------------------------------------------------------- line protocol


@functools.lru_cache(maxsize=4096)  # names and keys repeat on every record
def escape_measurement(name: str) -> str:
    """A measurement name in line protocol (commas and spaces escaped; line breaks become
    spaces and backslashes '/')."""
    return _clean(name).replace(",", "\\,").replace(" ", "\\ ")


@functools.lru_cache(maxsize=4096)
def escape_key(text: str) -> str:
    """A tag key, tag value or field key in line protocol (commas, '=' and spaces escaped; line
    breaks become spaces and backslashes '/', which InfluxDB 1.x cannot always escape)."""
    return _clean(text).replace(",", "\\,").replace("=", "\\=").replace(" ", "\\ ")


def _clean(text: str) -> str:
    # Outside string fields line protocol has no escape for line breaks, and InfluxDB 1.x has
    # none for a backslash before ',', '=', ' ' or at the end: both are replaced.
    return str(text).replace("\r", " ").replace("\n", " ").replace("\\", "/")


def field_value(value: Any) -> str | None:
    """A field value in line protocol, or None for what InfluxDB cannot hold (NaN, None, lists)."""
    if value is True:
        return "true"
    if value is False:
        return "false"
    if isinstance(value, int | float):
        number = float(value)
        return repr(number) if math.isfinite(number) else None
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')  # line breaks may stay
        return f'"{escaped}"'
    return None


def _stamp(time: float, precision: str) -> int:
    return round(time * _PRECISION[precision])


def _line(
    measurement: str, tags: Mapping[str, str], fields: Mapping[str, Any], stamp: int
) -> str | None:
    parts = [escape_measurement(measurement)]
    parts.extend(f"{escape_key(k)}={escape_key(v)}" for k, v in sorted(tags.items()) if v != "")
    encoded = []
    for key, value in fields.items():
        text = field_value(value)
        if text is not None and key:
            encoded.append(f"{escape_key(key)}={text}")
    if not encoded:
        return None
    return f"{','.join(parts)} {','.join(encoded)} {stamp}"


def _adaptation_lines(record: Mapping[str, Any], stamp: int) -> list[str | None]:
    """The ``adaptation`` points of a record on which some event is true."""
    plan = record.get("plan")
    plan_tag = "" if plan is None or isinstance(plan, bool) else _clean(str(plan))
    lines = []
    for event in ADAPTATION_EVENTS:
        if record.get(event) is True:
            fields: dict[str, Any] = {"value": True}
            broken = record.get("broken_rules")
            if isinstance(broken, list | tuple) and broken:
                fields["broken_rules"] = ",".join(str(name) for name in broken)
            elif isinstance(broken, str) and broken:
                fields["broken_rules"] = broken
            explanation = record.get("explanation")
            if isinstance(explanation, str) and explanation:
                fields["explanation"] = explanation
            lines.append(_line("adaptation", {"event": event, "plan": plan_tag}, fields, stamp))
    return lines


def _entry_lines(entries: Iterable[Entry], factor: int) -> list[str]:
    """The lines of a batch: a line as it is, a ``(time, record)`` as :func:`record_to_points`
    gives it, timestamps in ``1 / factor`` seconds. One loop for the batch: a record of plain
    knowledge (nearly every one) costs one line's formatting."""
    lines: list[str] = []
    for entry in entries:
        if isinstance(entry, str):
            lines.append(entry)
            continue
        time, record = entry
        stamp = round(time * factor)
        stage = record.get("stage")
        if isinstance(stage, str) and stage:
            fields = {"start": float(time), "duration": record.get("duration")}
            line = _line("maple_stage", {"stage": stage}, fields, stamp)
            if line is not None:
                lines.append(line)
        if not _EVENTS.isdisjoint(record):
            lines.extend(line for line in _adaptation_lines(record, stamp) if line is not None)
        knowledge = []
        for key, value in record.items():
            if key not in _NOT_KNOWLEDGE and key:
                text = field_value(value)
                if text is not None:
                    knowledge.append(f"{escape_key(key)}={text}")
        if knowledge:
            lines.append(f"knowledge {','.join(knowledge)} {stamp}")
    return lines


def record_to_points(
    time: float, record: Mapping[str, Any], *, precision: str = "u"
) -> list[str]:
    """The line-protocol lines of one trace record at ``time`` seconds (see the module doc).

    ``precision`` is the timestamp unit (``s``, ``ms``, ``u``, ``ns``) the lines are written in;
    :class:`InfluxWriter` passes its own.
    """
    if precision not in _PRECISION:
        raise CommError(f"unknown precision {precision!r}: use one of {', '.join(_PRECISION)}")
    return _entry_lines([(time, record)], _PRECISION[precision])


def verdict_to_point(
    property: str,
    time: float,
    value: bool | None,
    *,
    index: int | None = None,
    precision: str = "u",
) -> str | None:
    """``verdict,property=NAME value=true|false[,index=i] STAMP``; None for an inconclusive
    verdict (``value`` None), which InfluxDB has no value for."""
    if value is None:
        return None
    fields: dict[str, Any] = {"value": bool(value)}
    if index is not None:
        fields["index"] = index
    return _line("verdict", {"property": property}, fields, _stamp(time, precision))


# --------------------------------------------------------------------------- sinks


class _Sink(Protocol):
    def send(self, lines: list[str]) -> None: ...

    def close(self) -> None: ...


class _HttpSink:
    """``POST /write?db=…&precision=…`` on one kept-alive connection; creates the database once
    if InfluxDB says it does not exist."""

    def __init__(self, url: str, database: str, precision: str, timeout: float) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise CommError(
                f"bad InfluxDB URL {url!r}: expected http://HOST:PORT (InfluxDB 1.x HTTP API)"
            )
        if not isinstance(database, str) or not database:
            raise CommError("an InfluxDB database name is needed (e.g. 'rasm')")
        self.url = url
        self.host = parts.hostname
        self.port = parts.port or (443 if parts.scheme == "https" else 8086)
        self.https = parts.scheme == "https"
        self.database = database
        self.timeout = timeout
        self.path = "/write?" + urlencode({"db": database, "precision": precision})
        self._conn: http.client.HTTPConnection | None = None
        self._created = False

    def _connection(self) -> http.client.HTTPConnection:
        if self._conn is None:
            kind = http.client.HTTPSConnection if self.https else http.client.HTTPConnection
            self._conn = kind(self.host, self.port, timeout=self.timeout)
        return self._conn

    def _post(self, path: str, body: bytes, content_type: str) -> tuple[int, str]:
        for attempt in (1, 2):  # a kept-alive connection the server closed: reconnect once
            conn = self._connection()
            try:
                conn.request("POST", path, body=body, headers={"Content-Type": content_type})
                response = conn.getresponse()
                return response.status, response.read().decode("utf-8", "replace")
            except (OSError, http.client.HTTPException) as exc:
                self.close()
                if attempt == 2:
                    raise CommError(f"InfluxDB at {self.url} unreachable: {exc}") from exc
        raise AssertionError("unreachable")

    def create_database(self) -> None:
        quoted = self.database.replace("\\", "\\\\").replace('"', '\\"')
        body = urlencode({"q": f'CREATE DATABASE "{quoted}"'}).encode()
        status, text = self._post("/query", body, "application/x-www-form-urlencoded")
        if status != 200 or '"error"' in text:
            raise CommError(f"InfluxDB at {self.url}: cannot create {self.database!r}: {text}")
        self._created = True

    def send(self, lines: list[str]) -> None:
        body = ("\n".join(lines) + "\n").encode("utf-8")
        status, text = self._post(self.path, body, "text/plain; charset=utf-8")
        if status == 404 and "database not found" in text and not self._created:
            self.create_database()
            status, text = self._post(self.path, body, "text/plain; charset=utf-8")
        if status != 204:
            raise CommError(
                f"InfluxDB at {self.url} refused {len(lines)} point(s): {status} {text.strip()}"
            )

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


class _FileSink:
    """Appends batches to a file, unbuffered: a batch the disk refuses is cut off again (the
    file keeps whole lines) and raises; nothing is left behind to fail at closing."""

    def __init__(self, path: Path, append: bool = True) -> None:
        self.path = path
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._out = open(path, "ab" if append else "wb", buffering=0)  # noqa: SIM115
        except OSError as exc:
            raise CommError(f"creating the timing file {path} failed: {describe_error(exc)}"
                            ) from None
        self._size = self._out.seek(0, os.SEEK_END)

    def send(self, lines: list[str]) -> None:
        data = ("\n".join(lines) + "\n").encode("utf-8")
        view = memoryview(data)
        try:
            while view:
                view = view[self._out.write(view) or 0:]
        except OSError:
            with contextlib.suppress(OSError):
                os.ftruncate(self._out.fileno(), self._size)
                self._out.seek(self._size)
            raise
        self._size += len(data)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._out.close()


# --------------------------------------------------------------------------- the writer


@dataclass
class WriterStats:
    """Counters of an :class:`InfluxWriter`: points ``written``, ``dropped`` (queue full, never
    sent), ``failed`` (sent but refused, or the server unreachable), ``batches`` sent."""

    written: int = 0
    dropped: int = 0
    failed: int = 0
    batches: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class InfluxWriter:
    """Writes line-protocol points to InfluxDB 1.x (``url`` = ``http://host:8086``, ``database``)
    from a background thread; :meth:`to_file` makes one that appends to a file instead.

    :meth:`write` never blocks on the network: lines wait in a queue of at most ``max_queue``
    (more are dropped and counted in ``stats.dropped``) and go out in batches of at most
    ``batch_size``, at the latest ``flush_interval`` seconds after they came. A batch the server
    refuses, or that cannot reach it, is counted in ``stats.failed`` and logged; the writer goes
    on. The database is created if it does not exist. Timestamps are in ``precision`` units.

    Feed it the loop's records with ``writer.write_record(time, record)`` (the signature of a
    trace observer) and verdicts with ``writer.write_verdict(verdict)``.
    """

    def __init__(
        self,
        url: str,
        database: str = "rasm",
        *,
        precision: str = "u",
        batch_size: int = 1000,
        flush_interval: float = 0.5,
        max_queue: int = 100_000,
        timeout: float = 5.0,
        _sink: _Sink | None = None,
    ) -> None:
        if precision not in _PRECISION:
            raise CommError(f"unknown precision {precision!r}: use one of {', '.join(_PRECISION)}")
        if batch_size < 1 or max_queue < 1 or not flush_interval > 0:
            raise CommError("batch_size and max_queue must be >= 1, flush_interval > 0")
        self.url = url
        self.database = database
        self.precision = precision
        self.batch_size = batch_size
        self.flush_interval = float(flush_interval)
        self.max_queue = max_queue
        self.stats = WriterStats()
        self._sink: _Sink = _sink or _HttpSink(url, database, precision, timeout)
        # a batch that cannot be written is logged once, the later ones counted
        target = url[len("file:"):] if url.startswith("file:") else url
        self.guard = WriteGuard("timing " + ("file" if url.startswith("file:") else "server"),
                                target, unit="points", logger=_log)
        self._queue: deque[Entry] = deque()
        # full batches formatted by the writer that filled them, in order: (entries, lines)
        self._ready: deque[tuple[int, list[str] | None]] = deque()
        self._held = 0  # entries in _ready
        self._cond = threading.Condition()
        self._accepted = 0  # lines ever queued
        self._done = 0  # lines ever taken off the queue and sent (or failed)
        self._urgent = False  # a flush() is waiting: do not wait for the batch to fill
        self._closing = False
        self._thread = threading.Thread(target=self._run, name="rasm-influx", daemon=True)
        self._thread.start()

    @classmethod
    def to_file(
        cls,
        path: str | os.PathLike[str],
        *,
        precision: str = "u",
        append: bool = True,
        **options: Any,
    ):
        """A writer that appends the same lines to ``path`` (no server needed); ``append=False``
        starts the file afresh."""
        target = Path(path)
        sink = _FileSink(target, append)
        return cls(f"file:{target}", "", precision=precision, _sink=sink, **options)

    # -- feeding --------------------------------------------------------------------------------
    def write(self, lines: Iterable[str]) -> int:
        """Queue line-protocol lines; returns how many were queued (the rest were dropped)."""
        return self._put(lines)

    def write_record(self, time: float, record: Mapping[str, Any]) -> int:
        """Queue one trace record; its points (see :func:`record_to_points`) are formatted with
        the batch it goes out in, off the caller's thread. Returns 1, or 0 if it was dropped
        (a record counts as one entry of the queue)."""
        return self._put([(time, dict(record))])  # a copy: the caller may reuse its dict

    def _put(self, entries: Iterable[Entry]) -> int:
        if self._closing:
            raise CommError(f"the InfluxDB writer for {self.url} is closed")
        queued = 0
        with self._cond:
            for entry in entries:
                if len(self._queue) + self._held >= self.max_queue:
                    self.stats.dropped += 1
                    continue
                self._queue.append(entry)
                queued += 1
                if len(self._queue) >= self.batch_size:
                    # formatted here: in the writer's thread it would cost more CPU, the two
                    # threads taking turns at the interpreter while the loop runs
                    batch = self._batch()
                    self._ready.append((len(batch), self._format(batch)))
                    self._held += len(batch)
                    self._cond.notify_all()
            self._accepted += queued
            if queued and len(self._queue) == queued:
                self._cond.notify_all()  # the first lines of a batch start its timer
        return queued

    def _batch(self) -> list[Entry]:
        """The oldest entries of the queue, at most a batch (the lock is held)."""
        count = min(len(self._queue), self.batch_size)
        return [self._queue.popleft() for _ in range(count)]

    def _format(self, batch: list[Entry]) -> list[str] | None:
        """The lines of a batch; None (counted as failed when sent) if formatting failed."""
        try:
            return _entry_lines(batch, _PRECISION[self.precision])
        except Exception:  # a bug must not reach the loop, nor stop the writer: log, go on
            _log.exception("InfluxDB writer failed to format a batch")
            return None

    def write_verdict(self, verdict: Any) -> int:
        """Queue one verdict (anything with ``property``, ``index``, ``time``, ``value``)."""
        line = verdict_to_point(
            verdict.property, verdict.time, verdict.value,
            index=getattr(verdict, "index", None), precision=self.precision,
        )
        return self.write([line]) if line is not None else 0

    __call__ = write_record

    # -- draining -------------------------------------------------------------------------------
    def flush(self, timeout: float | None = 10.0) -> bool:
        """Send everything queued so far now; True once it is written or failed, False on
        timeout."""
        with self._cond:
            target = self._accepted
            self._urgent = True
            self._cond.notify_all()
            done = self._cond.wait_for(lambda: self._done >= target, timeout)
            return done

    @property
    def pending(self) -> int:
        """Lines queued and not yet sent."""
        with self._cond:
            return len(self._queue) + self._held

    def close(self, timeout: float = 10.0) -> None:
        """Send what is queued (at most ``timeout`` seconds), stop the thread, close the sink."""
        if self._closing:
            return
        self.flush(timeout)
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join(timeout)
        self._sink.close()

    @property
    def failure(self) -> WriteFailure | None:
        """The batches that could not be written (None: none)."""
        return self.guard.failure

    def __enter__(self) -> InfluxWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _take(self) -> tuple[int, list[str] | None] | None:
        """The next batch to send, as (entries, lines), or None once closing with none left."""
        with self._cond:
            while not self._queue and not self._ready:
                if self._closing:
                    return None
                self._urgent = False
                self._cond.wait()
            if not self._ready:
                deadline = _time.monotonic() + self.flush_interval
                while not self._ready and not self._urgent and not self._closing:
                    left = deadline - _time.monotonic()
                    if left <= 0:
                        break
                    self._cond.wait(left)
            if self._ready:  # taken from the queue before what is left in it
                count, lines = self._ready.popleft()
                self._held -= count
                return count, lines
            batch = self._batch()
            return len(batch), self._format(batch)

    def _run(self) -> None:
        while True:
            taken = self._take()
            if taken is None:
                return
            count, lines = taken
            try:
                if lines:
                    self._sink.send(lines)
                ok = lines is not None
            except (CommError, OSError) as exc:
                ok = False
                self.guard.fail(
                    "writing", exc, lost=len(lines or ()),
                    consequence="the run goes on; the points that cannot be written are "
                    "counted (the run summary shows them)",
                )
            except Exception:  # a bug must not kill the thread silently: log and go on
                ok = False
                _log.exception("InfluxDB writer failed on a batch")
            with self._cond:
                if ok:
                    self.stats.written += len(lines)
                    if lines:
                        self.guard.succeeded()
                    if lines:
                        self.stats.batches += 1
                else:  # not sent; a batch that could not even be formatted counts its entries
                    self.stats.failed += len(lines or ()) or count
                self._done += count
                if not self._queue and not self._ready:
                    self._urgent = False
                self._cond.notify_all()


def query(url: str, database: str, q: str, *, timeout: float = 10.0) -> list[dict[str, Any]]:
    """Run an InfluxQL query (``GET /query``) and return its ``series`` (each with ``name``,
    ``columns``, ``values``); raises :class:`CommError` on an error answer."""
    import urllib.request
    from urllib.error import URLError

    full = f"{url.rstrip('/')}/query?" + urlencode({"db": database, "q": q, "epoch": "u"})
    try:
        with urllib.request.urlopen(full, timeout=timeout) as response:  # noqa: S310 - http(s)
            answer = json.loads(response.read())
    except (URLError, OSError, ValueError) as exc:
        raise CommError(f"InfluxDB query at {url} failed: {exc}") from exc
    series: list[dict[str, Any]] = []
    for result in answer.get("results", []):
        if "error" in result:
            raise CommError(f"InfluxDB query {q!r} failed: {result['error']}")
        series.extend(result.get("series", []))
    return series
