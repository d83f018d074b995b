"""MCAP files, written record by record and read back whatever happened to them.

:class:`McapEncoder` gives the bytes of an MCAP file without chunks: the header, schemas and
channels, then one Message record per message, and at the end the summary (schemas, channels,
statistics) and the footer. Its writer hands each record to the operating system as it is made
(:class:`rasm.trace_mcap.McapTraceWriter`), so a process killed at any moment leaves every
message it wrote readable, as the JSONL trace does.

:class:`McapReader` reads any MCAP file, chunked or not, compressed (lz4, zstd) or not, and
checks what it reads instead of trusting it:

- with a summary (its chunk indexes), chunks are read by the index and merged in log-time order;
  without one (a file cut short: its writer was killed, or a write failed), the file is read
  record by record from the start;
- a chunk must decompress to its stated size, match its CRC (where the writer stored one), hold
  records that fit inside it, messages on known channels within its time range, and as many
  messages per channel as its message index lists;
- a chunk that fails any of these is left out whole and reported as a :class:`~rasm.losses.Damage`
  (where, why, its bytes, the messages its index lists and their topics, its time range); so is a
  record cut by the end of the file, bytes past which the records no longer make sense, and a
  file that ends without its summary (what its writer had not written yet is missing).

Damage is found as the messages are read: :attr:`McapReader.damage` is complete once
:meth:`McapReader.messages` has run to its end (damage found while opening is there at once).
"""

from __future__ import annotations

import heapq
import struct
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from rasm.errors import RasmError
from rasm.losses import Damage

__all__ = ["MAGIC", "Channel", "McapEncoder", "McapError", "McapReader", "Schema", "read_header"]

MAGIC = b"\x89MCAP0\r\n"

_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
_MESSAGE_INDEX, _CHUNK_INDEX, _STATISTICS, _SUMMARY_OFFSET, _DATA_END = 0x07, 0x08, 0x0B, 0x0E, 0x0F
_KNOWN = frozenset(range(0x01, 0x10))
_NAMES = {_CHUNK: "chunk", _MESSAGE: "message", _SCHEMA: "schema", _CHANNEL: "channel"}

_OP_LEN = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed CRC
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")


class McapError(RasmError):
    """A file that is not MCAP at all (no magic, no header): nothing in it can be read."""


@dataclass(frozen=True)
class Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class Channel:
    id: int
    schema_id: int
    topic: str
    encoding: str
    metadata: dict[str, str]


# ----------------------------------------------------------------------------- writing


def _string(text: str) -> bytes:
    data = text.encode("utf-8")
    return _U32.pack(len(data)) + data


def _record(op: int, content: bytes) -> bytes:
    return _OP_LEN.pack(op, len(content)) + content


def _string_map(entries: Mapping[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in entries.items())
    return _U32.pack(len(body)) + body


class McapEncoder:
    """The bytes of an unchunked MCAP file, record by record (no I/O: the caller writes them).

    :meth:`start` gives the magic and the header; :meth:`schema` and :meth:`channel` their
    records; :meth:`message` one Message record (counted for the statistics); :meth:`finish`
    the data end, the summary and the footer, given the number of bytes written before it.
    """

    def __init__(self, *, profile: str = "", library: str = "rasm") -> None:
        self.profile = profile
        self.library = library
        self._schemas: list[bytes] = []
        self._channels: list[bytes] = []
        self._counts: dict[int, int] = {}
        self._start: int | None = None
        self._end = 0

    def start(self) -> bytes:
        return MAGIC + _record(_HEADER, _string(self.profile) + _string(self.library))

    def schema(self, id: int, name: str, encoding: str, data: bytes) -> bytes:
        record = _record(_SCHEMA, _U16.pack(id) + _string(name) + _string(encoding)
                         + _U32.pack(len(data)) + data)
        self._schemas.append(record)
        return record

    def channel(self, id: int, schema_id: int, topic: str, encoding: str,
                metadata: Mapping[str, str] | None = None) -> bytes:
        record = _record(_CHANNEL, _U16.pack(id) + _U16.pack(schema_id) + _string(topic)
                         + _string(encoding) + _string_map(metadata or {}))
        self._channels.append(record)
        self._counts[id] = 0
        return record

    def message(self, channel: int, log_time: int, data: bytes, *, sequence: int = 0,
                publish_time: int | None = None) -> bytes:
        publish = log_time if publish_time is None else publish_time
        head = _MESSAGE_HEAD.pack(channel, sequence & 0xFFFFFFFF, log_time, publish)
        self._counts[channel] = self._counts.get(channel, 0) + 1
        self._start = log_time if self._start is None else min(self._start, log_time)
        self._end = max(self._end, log_time)
        return _OP_LEN.pack(_MESSAGE, len(head) + len(data)) + head + data

    def finish(self, written: int) -> bytes:
        """The end of the file, once ``written`` bytes of it are written."""
        data_end = _record(_DATA_END, _U32.pack(0))
        summary_start = written + len(data_end)
        parts: list[bytes] = []
        offsets: list[bytes] = []
        position = summary_start

        def group(op: int, records: list[bytes]) -> None:
            nonlocal position
            if not records:
                return
            length = sum(len(r) for r in records)
            offsets.append(_record(_SUMMARY_OFFSET, bytes([op]) + _U64.pack(position)
                                   + _U64.pack(length)))
            parts.extend(records)
            position += length

        counts = b"".join(_U16.pack(c) + _U64.pack(n) for c, n in sorted(self._counts.items()))
        statistics = _record(_STATISTICS, struct.pack(
            "<QHIIIIQQ", sum(self._counts.values()), len(self._schemas), len(self._channels),
            0, 0, 0, self._start or 0, self._end) + _U32.pack(len(counts)) + counts)
        group(_SCHEMA, self._schemas)
        group(_CHANNEL, self._channels)
        group(_STATISTICS, [statistics])
        summary = b"".join(parts)
        offset_start = summary_start + len(summary)
        offset_section = b"".join(offsets)
        footer_head = _OP_LEN.pack(_FOOTER, 20) + _U64.pack(summary_start) + _U64.pack(offset_start)
        crc = zlib.crc32(summary + offset_section + footer_head)
        return data_end + summary + offset_section + footer_head + _U32.pack(crc) + MAGIC


# ----------------------------------------------------------------------------- reading


class _Bad(Exception):
    """A part of the file that does not check out (caught where the damage is recorded)."""


@dataclass
class _Chunk:
    """A chunk record: where it is, and what its index (or the message indexes after it)
    says it holds."""

    offset: int
    length: int | None = None  # the whole record, opcode and length included
    start: int | None = None
    end: int | None = None
    counts: dict[int, int] | None = None  # messages per channel
    bad: str | None = None  # why it does not check out


@dataclass
class _Run:
    """Message records outside chunks, one after another from ``offset`` to ``end``."""

    offset: int
    end: int
    start: int  # the first one's log time


def _text(data: bytes, at: int) -> tuple[str, int]:
    (size,) = _U32.unpack_from(data, at)
    at += 4
    if at + size > len(data):
        raise _Bad("a string runs past its record")
    return data[at:at + size].decode("utf-8"), at + size


def _blob(data: bytes, at: int) -> tuple[bytes, int]:
    (size,) = _U32.unpack_from(data, at)
    at += 4
    if at + size > len(data):
        raise _Bad("a byte array runs past its record")
    return data[at:at + size], at + size


def _parse_schema(content: bytes) -> Schema:
    try:
        (id,) = _U16.unpack_from(content, 0)
        name, at = _text(content, 2)
        encoding, at = _text(content, at)
        data, _ = _blob(content, at)
    except (struct.error, UnicodeDecodeError) as exc:
        raise _Bad(f"a schema record does not parse ({exc})") from None
    return Schema(id, name, encoding, data)


def _parse_channel(content: bytes) -> Channel:
    try:
        id, schema_id = struct.unpack_from("<HH", content, 0)
        topic, at = _text(content, 4)
        encoding, at = _text(content, at)
        raw, _ = _blob(content, at)
        metadata: dict[str, str] = {}
        k = 0
        while k < len(raw):
            key, k = _text(raw, k)
            value, k = _text(raw, k)
            metadata[key] = value
    except (struct.error, UnicodeDecodeError) as exc:
        raise _Bad(f"a channel record does not parse ({exc})") from None
    return Channel(id, schema_id, topic, encoding, metadata)


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        return data
    try:
        if compression == "lz4":
            import lz4.frame

            return lz4.frame.decompress(data)
        if compression == "zstd":
            try:
                from compression import zstd  # Python 3.14
            except ImportError:
                try:
                    from backports import zstd
                except ImportError:
                    import zstandard

                    return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
            return zstd.decompress(data)
    except ImportError:
        raise _Bad(f"its compression {compression} needs a library that is not installed "
                   f"(pip install {'lz4' if compression == 'lz4' else 'zstandard'})") from None
    except Exception as exc:  # each library raises its own error class for bad input
        raise _Bad(f"it does not decompress ({compression}: {exc})") from None
    raise _Bad(f"its compression {compression!r} is not one MCAP defines")


def _header(stream: IO[bytes], name: str) -> tuple[str, str, int]:
    """The profile and library an MCAP file's header names, and where its data starts."""
    stream.seek(0)
    head = stream.read(8 + 9)
    if len(head) == 0:
        raise McapError(f"{name}: the file is empty")
    if head[:8] != MAGIC:
        raise McapError(f"{name}: not an MCAP file (it does not start with MCAP's magic bytes)")
    if len(head) < 17:
        raise McapError(f"{name}: the file ends inside its MCAP header")
    op, length = _OP_LEN.unpack_from(head, 8)
    content = stream.read(length) if op == _HEADER and length < 1 << 20 else b""
    if op != _HEADER or len(content) != length:
        raise McapError(f"{name}: its MCAP header is damaged or cut")
    try:
        profile, at = _text(content, 0)
        library, _ = _text(content, at)
    except (_Bad, struct.error, UnicodeDecodeError):
        raise McapError(f"{name}: its MCAP header is damaged") from None
    return profile, library, 17 + length


def read_header(path: str | Path) -> tuple[str, str]:
    """The profile (``ros2`` for a rosbag2 recording) and the library an MCAP file's header
    names, read without looking further; raises :class:`McapError` for a file that is not
    MCAP."""
    with open(path, "rb") as stream:
        profile, library, _ = _header(stream, str(path))
    return profile, library


class McapReader:
    """An MCAP file opened for reading (see the module doc). Close it, or use ``with``.

    :attr:`profile`, :attr:`schemas` and :attr:`channels` (by id) are known once it is open;
    :attr:`counts` gives the messages per channel the file declares (its statistics, its chunk
    indexes) or, read linearly, that it holds. :meth:`messages` yields ``(channel id, log time
    ns, data)`` in log-time order, leaving out every part that does not check out.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.name = str(path)
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.counts: dict[int, int] = {}
        self.profile = ""
        self.library = ""
        self.indexed = False  # read by its chunk indexes (else record by record)
        self._damage: dict[int, Damage] = {}  # by byte offset
        self._chunks: list[_Chunk] = []
        self._runs: list[_Run] = []
        self._data_start = 0
        self._data_end: int | None = None  # where the summary starts, if it can be trusted
        self._tail_damaged = False  # the records stop making sense before the end
        self._file: IO[bytes] = open(self.path, "rb")  # noqa: SIM115 - closed in close()
        try:
            self.size = self.path.stat().st_size
            self._open()
        except BaseException:
            self._file.close()
            raise

    def __enter__(self) -> McapReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._file.close()

    @property
    def damage(self) -> list[Damage]:
        """What could not be read, in file order (complete once :meth:`messages` ran)."""
        return [self._damage[k] for k in sorted(self._damage)]

    # -- opening ----------------------------------------------------------------------------

    def _read_at(self, offset: int, size: int) -> bytes:
        self._file.seek(offset)
        return self._file.read(size)

    def _open(self) -> None:
        self.profile, self.library, self._data_start = _header(self._file, self.name)
        if not self._read_summary():
            self._scan()

    def _read_summary(self) -> bool:
        """Read the summary (schemas, channels, chunk indexes, statistics); False when the file
        has none that can be trusted, or no chunk index to read the messages by."""
        if self.size < self._data_start + 37:
            return False
        tail = self._read_at(self.size - 37, 37)
        if tail[-8:] != MAGIC or tail[:9] != _OP_LEN.pack(_FOOTER, 20):
            return False
        summary_start, offset_start, crc = struct.unpack_from("<QQI", tail, 9)
        footer = self.size - 37
        if not summary_start or not self._data_start <= summary_start <= footer:
            return False
        section = self._read_at(summary_start, footer - summary_start)
        if crc and zlib.crc32(section + tail[:25]) != crc:
            return False  # a damaged summary is read around: the records are read one by one
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        chunks: list[_Chunk] = []
        counts: dict[int, int] | None = None
        first = 0
        at = 0
        limit = (offset_start - summary_start) if offset_start else len(section)
        try:
            while at < limit:
                op, length = _OP_LEN.unpack_from(section, at)
                content = section[at + 9:at + 9 + length]
                if len(content) != length:
                    return False
                if op == _SCHEMA:
                    schema = _parse_schema(content)
                    schemas[schema.id] = schema
                elif op == _CHANNEL:
                    channel = _parse_channel(content)
                    channels[channel.id] = channel
                elif op == _CHUNK_INDEX:
                    chunks.append(self._chunk_index(content, summary_start))
                elif op == _STATISTICS:
                    (first,) = _U64.unpack_from(content, 26)  # the first message's log time
                    (size,) = _U32.unpack_from(content, 42)
                    counts = {c: n for c, n in struct.iter_unpack("<HQ", content[46:46 + size])}
                at += 9 + length
        except (_Bad, struct.error):
            return False
        if not chunks:
            # no chunk index (an unchunked file): its records are read one by one up to the
            # summary, and its channels are known from it (or from the records themselves)
            self.schemas, self.channels = schemas, channels
            self._data_end = summary_start
            if not channels or counts is None:
                return False
            # closed in order (a rasm trace): read in one pass, each record checked as it comes
            self.counts = counts
            self._runs = [_Run(self._data_start, summary_start, first)]
            return True
        self.schemas, self.channels = schemas, channels
        self._chunks = sorted(chunks, key=lambda c: c.offset)
        if counts is not None:
            self.counts = counts
        else:
            for chunk in self._chunks:
                for channel, n in (chunk.counts or {}).items():
                    self.counts[channel] = self.counts.get(channel, 0) + n
        self._data_end = summary_start
        self.indexed = True
        return True

    def _chunk_index(self, content: bytes, summary_start: int) -> _Chunk:
        start, end, offset, length = struct.unpack_from("<QQQQ", content, 0)
        (size,) = _U32.unpack_from(content, 32)
        pairs = sorted((o, c) for c, o in struct.iter_unpack("<HQ", content[36:36 + size]))
        (index_length,) = _U64.unpack_from(content, 36 + size)
        if not self._data_start <= offset < summary_start or offset + length > summary_start:
            raise _Bad("a chunk index points outside the data")
        # each message index record: opcode, length, channel (2), array length (4), 16 a message
        counts: dict[int, int] = {}
        bounds = [o for o, _ in pairs] + [offset + length + index_length]
        for (position, channel), following in zip(pairs, bounds[1:], strict=False):
            counts[channel] = max(0, (following - position - 15) // 16)
        return _Chunk(offset, length, start, end, counts if pairs else None)

    def _scan(self) -> None:
        """Walk the records from the start (a file without a usable summary): note the chunks
        and the runs of messages outside chunks, the schemas and channels (inside chunks too),
        and where the records stop making sense."""
        summary = self._data_end is not None
        end = self._data_end if self._data_end is not None else self.size
        self._data_end = end
        at = self._data_start
        run: _Run | None = None
        chunk: _Chunk | None = None
        last_time: int | None = None
        counted: dict[int, int] = {}
        stream = self._file
        stream.seek(at)
        ended = False
        while at < end:
            head = stream.read(9)
            if len(head) < 9:
                self._cut(at, "a record", end - at, last_time)
                break
            op, length = _OP_LEN.unpack(head)
            if op not in _KNOWN:
                self._lost_sync(at, end, last_time, f"byte {at} is no MCAP record (opcode {op})")
                break
            if at + 9 + length > end:
                self._cut(at, f"a {_NAMES.get(op, 'record')}", end - at, last_time,
                          head=stream.read(min(length, 64)) if op == _CHUNK else b"")
                break
            if op == _MESSAGE:
                content = stream.read(length)
                if length < 22:
                    self._lost_sync(at, end, last_time, f"the message at byte {at} is too short")
                    break
                channel, _, log_time, _ = _MESSAGE_HEAD.unpack_from(content, 0)
                if channel not in self.channels:
                    self._lost_sync(at, end, last_time,
                                    f"the message at byte {at} is on channel {channel}, which "
                                    "no channel record defines")
                    break
                counted[channel] = counted.get(channel, 0) + 1
                if run is None:
                    run = _Run(at, at + 9 + length, log_time)
                    self._runs.append(run)
                run.end = at + 9 + length
                last_time = log_time if last_time is None else max(last_time, log_time)
            else:
                run = None
                if op == _CHUNK:
                    chunk = _Chunk(at, 9 + length)
                    self._chunks.append(chunk)
                    try:
                        messages = self._chunk_messages(chunk, stream.read(length))
                    except _Bad as bad:
                        chunk.bad = str(bad)  # reported below, once its message index is read
                    else:
                        for _, channel, _ in messages:
                            counted[channel] = counted.get(channel, 0) + 1
                        if chunk.end is not None:
                            last_time = chunk.end if last_time is None else max(last_time,
                                                                                chunk.end)
                elif op == _MESSAGE_INDEX:
                    content = stream.read(length)
                    if chunk is not None and len(content) >= 6:
                        (channel,) = _U16.unpack_from(content, 0)
                        (size,) = _U32.unpack_from(content, 2)
                        if chunk.counts is None:
                            chunk.counts = {}
                        chunk.counts[channel] = size // 16
                elif op in (_SCHEMA, _CHANNEL):
                    try:
                        self._define(op, stream.read(length))
                    except _Bad as bad:
                        self._lost_sync(at, end, last_time, str(bad))
                        break
                elif op in (_DATA_END, _FOOTER):
                    ended = True
                    break
                else:
                    stream.seek(length, 1)
            at += 9 + length
        self.counts = counted
        for bad in self._chunks:
            if bad.bad:
                self._bad_chunk(bad, bad.bad)
        if not ended and not summary and not self._tail_damaged:
            # nothing cut or garbled, but no summary: the writer never closed the file
            self._damage[self.size] = Damage(
                self.name, "the end of the file",
                "it ends without MCAP's summary and footer: its writer stopped before closing "
                "it (killed, or a write failed), so what it had not written yet is missing",
                start_ns=last_time,
            )

    def _define(self, op: int, content: bytes) -> None:
        if op == _SCHEMA:
            schema = _parse_schema(content)
            self.schemas.setdefault(schema.id, schema)
        else:
            channel = _parse_channel(content)
            self.channels.setdefault(channel.id, channel)

    def _cut(self, at: int, what: str, present: int, after: int | None, head: bytes = b"") -> None:
        """A record the end of the file cuts (of which ``head``: a chunk's first bytes)."""
        self._tail_damaged = True
        start = end = None
        if len(head) >= 16:
            start, end = struct.unpack_from("<QQ", head, 0)
        self._damage[at] = Damage(
            self.name, f"{what} at byte {at:,}",
            "the file ends inside it (cut: its writer was killed, or a write failed)",
            lost_bytes=present, start_ns=start if start is not None else after, end_ns=end,
        )

    def _lost_sync(self, at: int, end: int, after: int | None, why: str) -> None:
        self._tail_damaged = True
        self._damage[at] = Damage(
            self.name, f"the bytes from {at:,} to the end of the data",
            f"{why}, so the records after it cannot be found", lost_bytes=end - at,
            start_ns=after,
        )

    # -- chunks -----------------------------------------------------------------------------

    def _chunk_messages(self, chunk: _Chunk, content: bytes | None = None
                        ) -> list[tuple[int, int, bytes]]:
        """The ``(log time, channel, data)`` of a chunk's messages in log-time order; raises
        _Bad where the chunk does not check out."""
        if content is None:
            raw = self._read_at(chunk.offset, chunk.length or 0)
            if len(raw) < 9:
                raise _Bad("the file ends inside it")
            op, length = _OP_LEN.unpack_from(raw, 0)
            if op != _CHUNK or 9 + length != chunk.length:
                raise _Bad("the chunk index does not point at a chunk of its length")
            content = raw[9:]
            if len(content) != length:
                raise _Bad("the file ends inside it")
        try:
            start, end, size, crc = _CHUNK_HEAD.unpack_from(content, 0)
            compression, at = _text(content, 28)
            (stored,) = _U64.unpack_from(content, at)
        except (struct.error, UnicodeDecodeError, _Bad):
            raise _Bad("its header does not parse") from None
        if chunk.start is None:
            chunk.start, chunk.end = start, end
        at += 8
        if at + stored > len(content):
            raise _Bad("its records run past its end")
        if size > 1 << 32:
            raise _Bad(f"it claims {size:,} bytes uncompressed")
        data = _decompress(compression, content[at:at + stored], size)
        if len(data) != size:
            raise _Bad(f"it holds {len(data):,} bytes, its header says {size:,}")
        if crc and zlib.crc32(data) != crc:
            raise _Bad("its CRC does not match its bytes")
        messages: list[tuple[int, int, bytes]] = []
        counts: dict[int, int] = {}
        k = 0
        while k < size:
            if size - k < 9:
                raise _Bad("a record inside it is cut")
            op, length = _OP_LEN.unpack_from(data, k)
            if op not in _KNOWN or k + 9 + length > size:
                raise _Bad(f"the bytes at {k:,} inside it are no record that fits")
            if op == _MESSAGE:
                if length < 22:
                    raise _Bad("a message inside it is too short")
                channel, _, log_time, _ = _MESSAGE_HEAD.unpack_from(data, k + 9)
                if channel not in self.channels:
                    raise _Bad(f"a message inside it is on channel {channel}, which no channel "
                               "record defines")
                if not start <= log_time <= end:
                    raise _Bad("a message inside it is logged outside the chunk's time range")
                messages.append((log_time, channel, data[k + 31:k + 9 + length]))
                counts[channel] = counts.get(channel, 0) + 1
            elif op in (_SCHEMA, _CHANNEL):
                self._define(op, data[k + 9:k + 9 + length])
            k += 9 + length
        listed = chunk.counts
        if listed is not None and (
            any(counts.get(c, 0) != n for c, n in listed.items())
            # the summary's chunk index names every channel the chunk holds; read record by
            # record, a message index cut off by the end of the file names none
            or (self.indexed and any(c not in listed for c in counts))
        ):
            raise _Bad(f"it holds {sum(counts.values()):,} messages, its index lists "
                       f"{sum(listed.values()):,}")
        messages.sort(key=lambda m: m[0])
        return messages

    def _bad_chunk(self, chunk: _Chunk, why: str) -> None:
        chunk.bad = why
        counts = chunk.counts
        topics = None
        if counts is not None:
            topics = tuple(sorted({self.channels[c].topic if c in self.channels else f"channel {c}"
                                   for c, n in counts.items() if n}))
        self._damage[chunk.offset] = Damage(
            self.name, f"chunk at byte {chunk.offset:,}", why, lost_bytes=chunk.length,
            messages=sum(counts.values()) if counts is not None else None,
            start_ns=chunk.start, end_ns=chunk.end, topics=topics,
        )

    # -- messages ---------------------------------------------------------------------------

    def messages(self, channels: set[int] | None = None) -> Iterator[tuple[int, int, bytes]]:
        """``(channel id, log time ns, data)`` of the messages on ``channels`` (default: all),
        in log-time order; what does not check out is left out and added to :attr:`damage`."""
        sources = []
        for n, chunk in enumerate(self._chunks):
            if chunk.bad:
                continue
            if channels is not None and chunk.counts is not None and not any(
                chunk.counts.get(c) for c in channels
            ):
                continue
            sources.append(self._from_chunk(chunk, n, channels))
        for n, run in enumerate(self._runs):
            sources.append(self._from_run(run, len(self._chunks) + n, channels))
        for time, _, channel, data in heapq.merge(*sources, key=lambda m: (m[0], m[1])):
            if data is not None:
                yield channel, time, data

    def _from_chunk(self, chunk: _Chunk, order: int, channels: set[int] | None):
        # a first item at the chunk's start time: it is read only when the merge gets there
        yield (chunk.start or 0, -1, 0, None)
        try:
            messages = self._chunk_messages(chunk)
        except _Bad as bad:
            self._bad_chunk(chunk, str(bad))
            return
        position = order << 32
        for k, (time, channel, data) in enumerate(messages):
            if channels is None or channel in channels:
                yield (time, position + k, channel, data)

    def _from_run(self, run: _Run, order: int, channels: set[int] | None):
        """The records from ``run.offset`` to ``run.end``, checked as they are read (in file
        order; a chunk among them gives its messages in log-time order)."""
        yield (run.start, -1, 0, None)
        stream = self._file
        at, end = run.offset, run.end
        position = order << 32
        last: int | None = None
        while at < end:
            stream.seek(at)  # the merge may have read another part of the file meanwhile
            head = stream.read(9)
            if len(head) < 9:
                self._cut(at, "a record", end - at, last)
                return
            op, length = _OP_LEN.unpack(head)
            if op not in _KNOWN:
                self._lost_sync(at, end, last, f"byte {at:,} is no MCAP record (opcode {op})")
                return
            if at + 9 + length > end:
                self._cut(at, f"a {_NAMES.get(op, 'record')}", end - at, last)
                return
            if op in (_DATA_END, _FOOTER):
                return
            content = stream.read(length) if op in (_MESSAGE, _SCHEMA, _CHANNEL, _CHUNK) else b""
            if op == _MESSAGE:
                channel = _U16.unpack_from(content, 0)[0] if length >= 22 else None
                if channel is None or channel not in self.channels:
                    self._lost_sync(at, end, last, f"the message at byte {at:,} is not one of "
                                    "a channel the file defines")
                    return
                time = _MESSAGE_HEAD.unpack_from(content, 0)[2]
                if channels is None or channel in channels:
                    yield (time, position, channel, content[22:])
                position += 1
                last = time
            elif op == _CHUNK:
                chunk = _Chunk(at, 9 + length)
                try:
                    messages = self._chunk_messages(chunk, content)
                except _Bad as bad:
                    self._bad_chunk(chunk, str(bad))
                else:
                    for time, channel, data in messages:
                        if channels is None or channel in channels:
                            yield (time, position, channel, data)
                        position += 1
            elif op in (_SCHEMA, _CHANNEL):
                try:
                    self._define(op, content)
                except _Bad as bad:
                    self._lost_sync(at, end, last, str(bad))
                    return
            at += 9 + length
