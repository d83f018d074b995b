"""The adaptation trace as MCAP: what ``rasm run --trace OUT.mcap`` writes, Foxglove opens.

Every trace record is one message on the channel ``/rasm/trace``, JSON-encoded exactly as
its JSONL line (``time`` first, then what it updates), logged at the record's time (in
nanoseconds; the platform's timeline, so a simulated run starts at the epoch and a replay at
the recording's own times). The channel's JSON schema names the keys the loop writes, so
Foxglove's plots offer ``/rasm/trace.velocity`` and the like.

MCAP writes in chunks: a process killed mid-run loses the records of its last chunk (at most
:data:`CHUNK_BYTES`); the JSONL trace, flushed per record, loses none. ``rasm check`` reads an
MCAP trace back (:func:`read_mcap_trace`).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from rasm.errors import RasmError
from rasm.loop import LOOP_SIGNAL_TYPES
from rasm.trace import TraceWriter, format_line

__all__ = ["CHANNEL", "CHUNK_BYTES", "McapTraceWriter", "is_mcap_trace", "read_mcap_trace"]

CHANNEL = "/rasm/trace"
CHUNK_BYTES = 64 * 1024

_JSON_TYPES = {"float": "number", "int": "integer", "bool": "boolean", "str": "string"}


def _schema() -> bytes:
    properties: dict[str, Any] = {"time": {"type": "number", "description": "seconds"}}
    for key, kind in LOOP_SIGNAL_TYPES.items():
        if kind in _JSON_TYPES and key != "time":
            properties[key] = {"type": _JSON_TYPES[kind]}
    schema = {
        "title": "rasm trace record",
        "type": "object",
        "properties": properties,
        "additionalProperties": True,
    }
    return json.dumps(schema).encode()


class McapTraceWriter(TraceWriter):
    """A :class:`~rasm.trace.TraceWriter` writing an MCAP file (see the module doc)."""

    def __init__(self, path: str | Path) -> None:
        from mcap.writer import Writer

        super().__init__(None)  # no JSONL file: this writer keeps its own
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: IO[bytes] | None = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._mcap = Writer(self._file, chunk_size=CHUNK_BYTES)
        self._mcap.start(profile="", library="rasm")
        schema = self._mcap.register_schema("rasm.TraceRecord", "jsonschema", _schema())
        self._channel = self._mcap.register_channel(CHANNEL, "json", schema)

    def emit(self, time: float, record: dict[str, Any]) -> None:
        time = max(time, self.last_time)
        self.last_time = time
        self.records += 1
        if self._file is not None:
            stamp = max(0, round(time * 1e9))
            data = format_line(time, record).encode()
            self._mcap.add_message(self._channel, stamp, data, stamp, self.records)
        for observer in self.observers:
            observer(time, record)

    def flush(self) -> None:
        if self._file is not None:
            self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._mcap.finish()
            self._file.close()
            self._file = None


def is_mcap_trace(path: str | Path) -> bool:
    """Whether ``path`` is an MCAP file holding a rasm trace (a ``/rasm/trace`` JSON channel)."""
    file = Path(path)
    if file.suffix != ".mcap" or not file.is_file():
        return False
    from mcap.reader import make_reader

    try:
        with file.open("rb") as stream:
            summary = make_reader(stream).get_summary()
    except Exception:  # not MCAP, or truncated: not a trace this module wrote
        return False
    if summary is None:
        return False
    return any(
        c.topic == CHANNEL and c.message_encoding == "json" for c in summary.channels.values()
    )


def read_mcap_trace(path: str | Path) -> Iterator[str]:
    """The JSON lines of an MCAP trace, in log-time order (for :func:`rasm.trace.parse_trace`)."""
    from mcap.reader import make_reader

    with Path(path).open("rb") as stream:
        try:
            for _, _, message in make_reader(stream).iter_messages(topics=[CHANNEL]):
                yield message.data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise RasmError(f"{path}: a trace record is not UTF-8 text ({exc})") from None
