"""The adaptation trace as MCAP: what ``rasm run --trace OUT.mcap`` writes, Foxglove opens.

Every trace record is one message on the channel ``/rasm/trace``, JSON-encoded exactly as
its JSONL line (``time`` first, then what it updates), logged at the record's time (in
nanoseconds; the platform's timeline, so a simulated run starts at the epoch and a replay at
the recording's own times). The channel's JSON schema names the keys the loop writes, so
Foxglove's plots offer ``/rasm/trace.velocity`` and the like.

The file has no chunks: each record is one Message record handed to the operating system as
it is written, like a JSONL line, so a process killed at any moment leaves every record it
emitted readable (the summary and footer come at the end of a run that ends in order).
``rasm check`` reads an MCAP trace back (:func:`read_mcap_trace`), a cut one too: what its
writer never finished is reported as damage (:class:`McapTrace`).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rasm.errors import RasmError
from rasm.loop import LOOP_SIGNAL_TYPES
from rasm.losses import Damage
from rasm.mcapfile import McapEncoder, McapError, McapReader, read_header
from rasm.trace import TraceWriter, format_line

__all__ = ["CHANNEL", "McapTrace", "McapTraceWriter", "is_mcap_trace", "read_mcap_trace"]

CHANNEL = "/rasm/trace"

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
    """A :class:`~rasm.trace.TraceWriter` writing an MCAP file (see the module doc); a failed
    write is handled as the JSONL writer handles it (the file then ends without its summary,
    which is how a reader knows it was cut)."""

    def __init__(self, path: str | Path) -> None:
        self._mcap = McapEncoder(profile="", library="rasm")
        super().__init__(path)

    def _begin(self) -> None:
        self._put(self._mcap.start() + self._mcap.schema(1, "rasm.TraceRecord", "jsonschema",
                                                         _schema())
                  + self._mcap.channel(1, 1, CHANNEL, "json"))

    def _encode(self, time: float, record: dict[str, Any]) -> bytes:
        stamp = max(0, round(time * 1e9))
        data = format_line(time, record).encode()
        return self._mcap.message(1, stamp, data, sequence=self.records)

    def _finish(self) -> None:
        self._put(self._mcap.finish(self._size))


def is_mcap_trace(path: str | Path) -> bool:
    """Whether ``path`` is an MCAP file holding a rasm trace (a ``/rasm/trace`` JSON channel),
    whole or cut short."""
    file = Path(path)
    if file.suffix != ".mcap" or not file.is_file():
        return False
    try:
        if read_header(file)[0] == "ros2":  # a rosbag2 recording: nothing more to read
            return False
        with McapReader(file) as reader:
            return any(
                c.topic == CHANNEL and c.encoding == "json" for c in reader.channels.values()
            )
    except (McapError, OSError):
        return False


class McapTrace:
    """The JSON lines of an MCAP trace, in log-time order (for :func:`rasm.trace.parse_records`):
    iterate over it; each pass reads the file anew. :attr:`damage` lists what could not be read
    (complete after a pass)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.damage: list[Damage] = []
        try:
            read_header(self.path)  # an MCAP file, or an error now
        except McapError as exc:
            raise RasmError(str(exc)) from None

    def _open(self) -> McapReader:
        try:
            return McapReader(self.path)
        except McapError as exc:
            raise RasmError(str(exc)) from None

    def __iter__(self) -> Iterator[str]:
        with self._open() as reader:
            channels = {c.id for c in reader.channels.values() if c.topic == CHANNEL}
            try:
                for _, _, data in reader.messages(channels):
                    yield data.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise RasmError(f"{self.path}: a trace record is not UTF-8 text ({exc})") from None
            finally:
                self.damage = reader.damage


def read_mcap_trace(path: str | Path) -> Iterator[str]:
    """The JSON lines of an MCAP trace, in log-time order (for :func:`rasm.trace.parse_trace`);
    :class:`McapTrace` also says what was damaged."""
    return iter(McapTrace(path))
