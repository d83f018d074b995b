"""MCAP files read back whatever happened to them, on the ``mcap`` library's records.

:class:`McapReader` reads any MCAP file, chunked or not, compressed (lz4, zstd) or not, and
checks what it reads instead of trusting it. The ``mcap`` library parses every record
(:mod:`mcap.records`), decompresses chunks and checks their CRCs
(:func:`mcap.stream_reader.get_chunk_data_stream`, what its ``breakup_chunk`` uses); what this
module adds is the walk from record to record, which reports instead of raising or skipping:

- with a summary (its chunk indexes), chunks are read by the index and merged in log-time order;
  without one (a file cut short: its writer was killed, or a write failed), the file is read
  record by record from the start;
- a chunk must decompress to its stated size, match its CRC (where the writer stored one), hold
  records that fit inside it, messages on known channels within its time range, and as many
  messages per channel as its message index lists (the library's own ``breakup_chunk`` skips
  records it does not know and takes a record cut by the chunk's end as it is, so a chunk
  without a CRC is walked here, record by record);
- a chunk that fails any of these is left out whole and reported as a :class:`~rasm.losses.Damage`
  (where, why, its bytes, the messages its index lists and their topics, its time range); so is a
  record cut by the end of the file, bytes past which the records no longer make sense, and a
  file that ends without its summary (what its writer had not written yet is missing).

Damage is found as the messages are read: :attr:`McapReader.damage` is complete once
:meth:`McapReader.messages` has run to its end (damage found while opening is there at once).
The files rasm writes (``rasm run --trace OUT.mcap``) are written by the library's writer
(:mod:`rasm.trace_mcap`).
"""

from __future__ import annotations

import heapq
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import IO, Any

from mcap import records as mcap_records
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError as LibraryError
from mcap.opcode import Opcode
from mcap.stream_reader import get_chunk_data_stream

from rasm.errors import RasmError
from rasm.losses import Damage

__all__ = ["MAGIC", "Channel", "McapError", "McapReader", "Schema", "read_header"]

MAGIC = b"\x89MCAP0\r\n"

_KNOWN = frozenset(int(op) for op in Opcode)
_NAMES = {Opcode.CHUNK: "chunk", Opcode.MESSAGE: "message", Opcode.SCHEMA: "schema",
          Opcode.CHANNEL: "channel"}
_OP_LEN = struct.Struct("<BQ")
_FOOTER_LENGTH = 9 + 20 + 8  # the footer record and the closing magic
_MESSAGE_MIN = 22  # channel (2), sequence (4), log time (8), publish time (8)


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


class _Exact(ReadDataStream):
    """The library's record stream over one record's bytes, refusing a field that runs past
    them (the library's own stream takes what is left and goes on)."""

    def read(self, length: int) -> bytes:
        data = super().read(length)
        if len(data) != length:
            raise _Bad("a field runs past its record")
        return data


def _parse(read: Callable[..., Any], content: bytes, *args: Any) -> Any:
    """One record's content parsed by the library (``read`` is its record class's ``read``);
    :class:`_Bad` when it does not parse."""
    try:
        return read(_Exact(BytesIO(content)), *args)
    except (LibraryError, struct.error, UnicodeDecodeError) as exc:
        raise _Bad(f"a {read.__qualname__.split('.')[0].lower()} record does not parse "
                   f"({exc or type(exc).__name__})") from None


def _walk(data: bytes, end: int) -> Iterator[tuple[int, bytes]]:
    """The ``(opcode, content)`` of the records in ``data[:end]``, one after the other;
    :class:`_Bad` when one does not fit."""
    at = 0
    while at < end:
        if end - at < 9:
            raise _Bad("a record is cut")
        op, length = _OP_LEN.unpack_from(data, at)
        if at + 9 + length > end:
            raise _Bad("a record runs past its section")
        yield op, data[at + 9:at + 9 + length]
        at += 9 + length


def _message(content: bytes) -> Any:
    """A Message record's content, parsed by the library (channel_id, log_time, data)."""
    if len(content) < _MESSAGE_MIN:
        raise _Bad("a message record is too short")
    return _parse(mcap_records.Message.read, content, len(content))


def _decompressed(chunk: Any) -> bytes:
    """A chunk's records, decompressed and checked against its CRC (where its writer stored
    one) by the library; :class:`_Bad` when they cannot be."""
    from mcap.stream_reader import CRCValidationError

    if chunk.compression not in ("", "lz4", "zstd"):
        raise _Bad(f"its compression {chunk.compression!r} is not one MCAP defines")
    try:
        stream, length = get_chunk_data_stream(chunk, validate_crc=True)
    except CRCValidationError:
        raise _Bad("its CRC does not match its bytes") from None
    except LibraryError as exc:  # a compression whose library is not installed
        raise _Bad(f"its compression {chunk.compression} needs a library that is not installed "
                   f"({exc})") from None
    except Exception as exc:  # each compression library raises its own error for bad input
        raise _Bad(f"it does not decompress ({chunk.compression}: {exc})") from None
    return stream.read(length) if length else b""


def _schema(content: bytes) -> Schema:
    record = _parse(mcap_records.Schema.read, content)
    return Schema(record.id, record.name, record.encoding, record.data)


def _channel(content: bytes) -> Channel:
    record = _parse(mcap_records.Channel.read, content)
    return Channel(record.id, record.schema_id, record.topic, record.message_encoding,
                   dict(record.metadata))


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
    content = stream.read(length) if op == Opcode.HEADER and length < 1 << 20 else b""
    if op != Opcode.HEADER or len(content) != length:
        raise McapError(f"{name}: its MCAP header is damaged or cut")
    try:
        header = _parse(mcap_records.Header.read, content)
    except _Bad:
        raise McapError(f"{name}: its MCAP header is damaged") from None
    return header.profile, header.library, 17 + length


def read_header(path: str | Path) -> tuple[str, str]:
    """The profile (``ros2`` for a rosbag2 recording) and the library an MCAP file's header
    names, read without looking further; raises :class:`McapError` for a file that is not
    MCAP."""
    with open(path, "rb") as stream:
        profile, library, _ = _header(stream, str(path))
    return profile, library


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
        if self.size < self._data_start + _FOOTER_LENGTH:
            return False
        tail = self._read_at(self.size - _FOOTER_LENGTH, _FOOTER_LENGTH)
        if tail[-8:] != MAGIC or tail[:9] != _OP_LEN.pack(Opcode.FOOTER, 20):
            return False
        footer = _parse(mcap_records.Footer.read, tail[9:29])
        summary_start, offset_start = footer.summary_start, footer.summary_offset_start
        end = self.size - _FOOTER_LENGTH
        if not summary_start or not self._data_start <= summary_start <= end:
            return False
        section = self._read_at(summary_start, end - summary_start)
        if footer.summary_crc and zlib.crc32(section + tail[:25]) != footer.summary_crc:
            return False  # a damaged summary is read around: the records are read one by one
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        chunks: list[_Chunk] = []
        statistics = None
        limit = (offset_start - summary_start) if offset_start else len(section)
        try:
            for op, content in _walk(section, limit):
                if op == Opcode.SCHEMA:
                    schema = _schema(content)
                    schemas[schema.id] = schema
                elif op == Opcode.CHANNEL:
                    channel = _channel(content)
                    channels[channel.id] = channel
                elif op == Opcode.CHUNK_INDEX:
                    chunks.append(self._chunk_index(content, summary_start))
                elif op == Opcode.STATISTICS:
                    statistics = _parse(mcap_records.Statistics.read, content)
        except _Bad:
            return False
        counts = dict(statistics.channel_message_counts) if statistics is not None else None
        if not chunks:
            # no chunk index (an unchunked file): its records are read one by one up to the
            # summary, and its channels are known from it (or from the records themselves)
            self.schemas, self.channels = schemas, channels
            self._data_end = summary_start
            if not channels or counts is None:
                return False
            # closed in order (a rasm trace): read in one pass, each record checked as it comes
            self.counts = counts
            assert statistics is not None
            self._runs = [_Run(self._data_start, summary_start, statistics.message_start_time)]
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
        index = _parse(mcap_records.ChunkIndex.read, content)
        offset, length = index.chunk_start_offset, index.chunk_length
        if not self._data_start <= offset < summary_start or offset + length > summary_start:
            raise _Bad("a chunk index points outside the data")
        # each message index record: opcode, length, channel (2), array length (4), 16 a message
        pairs = sorted((o, c) for c, o in index.message_index_offsets.items())
        counts: dict[int, int] = {}
        bounds = [o for o, _ in pairs] + [offset + length + index.message_index_length]
        for (position, channel), following in zip(pairs, bounds[1:], strict=False):
            counts[channel] = max(0, (following - position - 15) // 16)
        return _Chunk(offset, length, index.message_start_time, index.message_end_time,
                      counts if pairs else None)

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
                          head=stream.read(min(length, 64)) if op == Opcode.CHUNK else b"")
                break
            if op == Opcode.MESSAGE:
                try:
                    message = _message(stream.read(length))
                except _Bad as bad:
                    self._lost_sync(at, end, last_time, f"the message at byte {at}: {bad}")
                    break
                channel, log_time = message.channel_id, message.log_time
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
                if op == Opcode.CHUNK:
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
                elif op == Opcode.MESSAGE_INDEX:
                    content = stream.read(length)
                    if chunk is not None:
                        try:
                            index = _parse(mcap_records.MessageIndex.read, content)
                        except _Bad:
                            pass  # cut off by the end of the file: the chunk's count unknown
                        else:
                            if chunk.counts is None:
                                chunk.counts = {}
                            chunk.counts[index.channel_id] = len(index.records)
                elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
                    try:
                        self._define(op, stream.read(length))
                    except _Bad as bad:
                        self._lost_sync(at, end, last_time, str(bad))
                        break
                elif op in (Opcode.DATA_END, Opcode.FOOTER):
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
        if op == Opcode.SCHEMA:
            schema = _schema(content)
            self.schemas.setdefault(schema.id, schema)
        else:
            channel = _channel(content)
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
            if op != Opcode.CHUNK or 9 + length != chunk.length:
                raise _Bad("the chunk index does not point at a chunk of its length")
            content = raw[9:]
            if len(content) != length:
                raise _Bad("the file ends inside it")
        try:
            record = _parse(mcap_records.Chunk.read, content)
        except _Bad:
            raise _Bad("its header does not parse, or its records run past its end") from None
        start, end, size = record.message_start_time, record.message_end_time, \
            record.uncompressed_size
        if chunk.start is None:
            chunk.start, chunk.end = start, end
        if size > 1 << 32:
            raise _Bad(f"it claims {size:,} bytes uncompressed")
        data = _decompressed(record)
        if len(data) != size:
            raise _Bad(f"it holds {len(data):,} bytes, its header says {size:,}")
        messages: list[tuple[int, int, bytes]] = []
        counts: dict[int, int] = {}
        # the records one after the other, each parsed by the library from one stream
        stream = _Exact(BytesIO(data))
        read_message = mcap_records.Message.read
        k = 0
        while k < size:
            if size - k < 9:
                raise _Bad("a record inside it is cut")
            op, length = _OP_LEN.unpack_from(data, k)
            if op not in _KNOWN or k + 9 + length > size:
                raise _Bad(f"the bytes at {k:,} inside it are no record that fits")
            stream.read(9)
            if op == Opcode.MESSAGE:
                if length < _MESSAGE_MIN:
                    raise _Bad("a message inside it is too short")
                message = read_message(stream, length)
                channel, log_time = message.channel_id, message.log_time
                if channel not in self.channels:
                    raise _Bad(f"a message inside it is on channel {channel}, which no channel "
                               "record defines")
                if not start <= log_time <= end:
                    raise _Bad("a message inside it is logged outside the chunk's time range")
                messages.append((log_time, channel, message.data))
                counts[channel] = counts.get(channel, 0) + 1
            else:
                content = stream.read(length)
                if op in (Opcode.SCHEMA, Opcode.CHANNEL):
                    self._define(op, content)
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
            if op in (Opcode.DATA_END, Opcode.FOOTER):
                return
            content = stream.read(length) if op in (
                Opcode.MESSAGE, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.CHUNK) else b""
            if op == Opcode.MESSAGE:
                try:
                    message = _message(content)
                except _Bad:
                    message = None
                if message is None or message.channel_id not in self.channels:
                    self._lost_sync(at, end, last, f"the message at byte {at:,} is not one of "
                                    "a channel the file defines")
                    return
                channel, time = message.channel_id, message.log_time
                if channels is None or channel in channels:
                    yield (time, position, channel, message.data)
                position += 1
                last = time
            elif op == Opcode.CHUNK:
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
            elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
                try:
                    self._define(op, content)
                except _Bad as bad:
                    self._lost_sync(at, end, last, str(bad))
                    return
            at += 9 + length
