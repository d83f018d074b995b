"""The adaptation trace as MCAP: what ``rasm run --trace OUT.mcap`` writes, ROS 2 tools decode
and Foxglove opens.

Every channel is a ROS 2 topic with a ROS 2 type (``ros2msg`` schema, ``cdr`` messages), so
``mcap-ros2-support``, ``ros2 bag`` and Foxglove decode all of it:

- ``/rasm/trace`` (``std_msgs/msg/String``): every trace record, its ``data`` the record's JSON
  line exactly as the JSONL trace holds it (``time`` first, then what it updates), logged at
  the record's time (in nanoseconds; the platform's timeline, so a simulated run starts at the
  epoch and a replay at the recording's own times);
- ``/rasm/verdict/<property>`` (``std_msgs/msg/Bool``): a property's verdict whenever it
  changes (``data`` false when violated or in error; an undecided verdict is not written), as
  the live verdict topics carry it (:meth:`McapTraceWriter.verdicts`);
- ``/rasm/robustness/<property>`` (``std_msgs/msg/Float64``): a property's robustness
  (``robustness_<property>``, ±inf included) with each trace record that carries it, so a plot
  of it needs no JSON parsing;
- each effector's topic (or service or action name) in the effector's own type: the message
  each action sent, or would have sent in a replay (:meth:`McapTraceWriter.message`).

The file has no chunks: each record is one Message record handed to the operating system as
it is written, like a JSONL line, so a process killed at any moment leaves every record it
emitted readable (the summary and footer come at the end of a run that ends in order). The
MCAP records are made by the ``mcap`` library's writer. ``rasm check`` reads an MCAP trace back
(:func:`read_mcap_trace`), a cut one too: what its writer never finished is reported as damage
(:class:`McapTrace`). :func:`open_trace_writer` gives a run the writer its trace file's name
asks for, this one or the JSONL one.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from rasm.errors import PlatformError, RasmError
from rasm.loop import ROBUSTNESS_PREFIX
from rasm.losses import Damage
from rasm.mcapfile import McapError, McapReader, read_header
from rasm.trace import TraceWriter, format_line

__all__ = [
    "CHANNEL",
    "McapTrace",
    "McapTraceWriter",
    "ROBUSTNESS_CHANNEL_PREFIX",
    "VERDICT_PREFIX",
    "is_mcap_trace",
    "open_trace_writer",
    "read_mcap_trace",
]

CHANNEL = "/rasm/trace"
VERDICT_PREFIX = "/rasm/verdict/"
ROBUSTNESS_CHANNEL_PREFIX = "/rasm/robustness/"

_CDR_HEADER = b"\x00\x01\x00\x00"  # little-endian plain CDR, as ROS 2 sends
_STRING = ("std_msgs/msg/String", "string data\n")
_BOOL = ("std_msgs/msg/Bool", "bool data\n")
_FLOAT64 = ("std_msgs/msg/Float64", "float64 data\n")
_U32 = struct.Struct("<I")
_F64 = struct.Struct("<d")  # alignment counts from after the header: no padding


def string_cdr(text: str) -> bytes:
    """A ``std_msgs/msg/String`` holding ``text``, as CDR."""
    data = text.encode("utf-8")
    return _CDR_HEADER + _U32.pack(len(data) + 1) + data + b"\x00"


def string_from_cdr(data: bytes) -> str:
    """The text of a ``std_msgs/msg/String`` in CDR; :class:`RasmError` when it is none."""
    if len(data) < 8 or data[1] not in (0, 1):
        raise RasmError("a /rasm/trace message is no std_msgs/msg/String")
    (size,) = struct.unpack_from("<I" if data[1] == 1 else ">I", data, 4)
    if size < 1 or 8 + size > len(data) or data[8 + size - 1] != 0:
        raise RasmError("a /rasm/trace message is no std_msgs/msg/String (its length does "
                        "not fit)")
    try:
        return data[8:8 + size - 1].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RasmError(f"a trace record is not UTF-8 text ({exc})") from None


class _Sink:
    """Where the ``mcap`` writer puts its bytes: held until the trace writer hands them to
    the operating system (its own write, with its failure handling), counted for ``tell``."""

    def __init__(self) -> None:
        self._parts: list[bytes] = []
        self._count = 0

    def write(self, data: bytes) -> int:
        self._parts.append(bytes(data))
        self._count += len(data)
        return len(data)

    def tell(self) -> int:
        return self._count

    def flush(self) -> None:
        pass

    def take(self) -> bytes:
        data = b"".join(self._parts)
        self._parts.clear()
        return data


class McapTraceWriter(TraceWriter):
    """A :class:`~rasm.trace.TraceWriter` writing an MCAP file (see the module doc); a failed
    write is handled as the JSONL writer handles it (the file then ends without its summary,
    which is how a reader knows it was cut)."""

    def __init__(self, path: str | Path) -> None:
        from mcap.writer import CompressionType, Writer

        self._sink = _Sink()
        self._mcap = Writer(self._sink, use_chunking=False, compression=CompressionType.NONE)
        self._schemas: dict[str, int] = {}  # type name -> schema id
        self._channels: dict[str, int] = {}  # topic -> channel id
        self._verdicts: dict[str, bool] = {}  # property -> the verdict written last
        self._sequence = 0
        super().__init__(path)

    def _channel(self, topic: str, typename: str, definition: str) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            schema = self._schemas.get(typename)
            if schema is None:
                schema = self._schemas[typename] = self._mcap.register_schema(
                    typename, "ros2msg", definition.encode("utf-8"))
            channel = self._channels[topic] = self._mcap.register_channel(topic, "cdr", schema)
        return channel

    def _add(self, channel: int, time: float, data: bytes) -> None:
        stamp = max(0, round(time * 1e9))
        self._sequence += 1
        self._mcap.add_message(channel, stamp, data, stamp, sequence=self._sequence)

    def _begin(self) -> None:
        self._mcap.start(profile="", library="rasm")
        self._channel(CHANNEL, *_STRING)
        self._put(self._sink.take())

    def _encode(self, time: float, record: dict[str, Any]) -> bytes:
        self._add(self._channels[CHANNEL], time, string_cdr(format_line(time, record)))
        for key, value in record.items():
            if (key.startswith(ROBUSTNESS_PREFIX) and isinstance(value, (int, float))
                    and not isinstance(value, bool)):
                channel = self._channel(
                    ROBUSTNESS_CHANNEL_PREFIX + key.removeprefix(ROBUSTNESS_PREFIX), *_FLOAT64)
                self._add(channel, time, _CDR_HEADER + _F64.pack(value))
        return self._sink.take()

    def _finish(self) -> None:
        self._mcap.finish()
        self._put(self._sink.take())

    def _extra(self, time: float, topic: str, typename: str, definition: str,
               data: bytes) -> None:
        """A message on a channel of its own, written as a trace record is (a failure stops
        the file there)."""
        if self._file is None:
            return
        try:
            self._add(self._channel(topic, typename, definition), time, data)
            self._put(self._sink.take())
        except OSError as exc:
            self._stop("writing", exc, time)

    def verdicts(self, verdicts: Iterable[Any]) -> None:
        """Each verdict that changes its property's: a ``std_msgs/msg/Bool`` on
        ``/rasm/verdict/<property>`` at the verdict's time (an undecided one is not written)."""
        for verdict in verdicts:
            if verdict.value is None and verdict.error is None:
                continue
            value = verdict.value is True and verdict.error is None
            if self._verdicts.get(verdict.property) == value:
                continue
            self._verdicts[verdict.property] = value
            self._extra(verdict.time, VERDICT_PREFIX + verdict.property, *_BOOL,
                        _CDR_HEADER + (b"\x01" if value else b"\x00"))

    def message(self, time: float, topic: str, typename: str, definition: str,
                data: bytes) -> None:
        """A message of ROS 2 type ``typename`` (its CDR ``data``; ``definition``, its
        ``.msg`` text with the types it uses, as rosbag2 records it) on ``topic``."""
        self._extra(time, topic, typename, definition, data)


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
                c.topic == CHANNEL and c.encoding in ("cdr", "json")
                for c in reader.channels.values()
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
            # a std_msgs/msg/String (cdr), or the JSON itself in traces written before
            cdr = {c.id for c in reader.channels.values()
                   if c.topic == CHANNEL and c.encoding == "cdr"}
            channels = cdr | {c.id for c in reader.channels.values()
                              if c.topic == CHANNEL and c.encoding == "json"}
            try:
                for channel, _, data in reader.messages(channels):
                    yield string_from_cdr(data) if channel in cdr else data.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise RasmError(f"{self.path}: a trace record is not UTF-8 text ({exc})") from None
            except RasmError as exc:
                raise RasmError(f"{self.path}: {exc}") from None
            finally:
                self.damage = reader.damage


def read_mcap_trace(path: str | Path) -> Iterator[str]:
    """The JSON lines of an MCAP trace, in log-time order (for :func:`rasm.trace.parse_trace`);
    :class:`McapTrace` also says what was damaged."""
    return iter(McapTrace(path))


def open_trace_writer(
    path: str | Path | None, *, max_bytes: int | None = None, keep: int = 4
) -> TraceWriter:
    """The writer of a run's trace: MCAP for a ``.mcap`` path (Foxglove opens it; not rotated),
    else JSONL, rotated by size with ``max_bytes`` (``keep`` files); None writes nothing."""
    if path is not None and str(path).endswith(".mcap"):
        if max_bytes is not None:
            raise PlatformError("an MCAP trace is not rotated: write JSONL to rotate")
        return McapTraceWriter(path)
    return TraceWriter(path, max_bytes=max_bytes, keep=keep)
