"""rosbag2 recordings: read them as a stream of decoded messages, and write them.

A recording is a bag folder (``metadata.yaml`` and its storage files) or one storage file,
MCAP (``.mcap``) or SQLite3 (``.db3``). Reading yields :class:`BagRecord` ``(time_ns, topic,
message)`` in log-time order, the message decoded into a dict (see :mod:`rasm.ros2.codec`),
file by file and chunk by chunk: a bag is never loaded whole.

A bag folder is read through its storage files, not through ``metadata.yaml``: rosbags matches
the topics of the two by QoS as well, and yields nothing for a topic whose QoS text differs
between them (rosbag2's own test bags do this), which would make a replay silently empty.

A message type comes from the type store when the bag's type hash agrees with it (or the bag
has none), else from the definition recorded in the bag. A message that does not decode is
skipped, counted in :attr:`BagReader.rejected` and logged once per topic.

What cannot be read is never skipped in silence: an MCAP file is read by
:class:`rasm.mcapfile.McapReader` (on the ``mcap`` library's records), which checks each
chunk (CRC, sizes, records, message index) and reports the chunks it leaves out, a cut end
and a missing summary; a SQLite3 file SQLite finds damaged is read row by row around the
damage. :attr:`BagReader.damage` lists it all, with the messages that did not decode, as
:class:`rasm.losses.Damage`.
"""

from __future__ import annotations

import heapq
import logging
import shutil
import sqlite3
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple
from urllib.parse import quote

from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.rosbag2 import Reader, ReaderError, StoragePlugin, Writer, WriterError
from rosbags.typesys import TypesysError, get_types_from_idl, get_types_from_msg
from ruamel.yaml import YAML, YAMLError

from rasm.losses import Damage
from rasm.ros2.codec import MessageCodec
from rasm.ros2.errors import BagError, MalformedMessage, RosError
from rasm.ros2.fieldread import field_reader
from rasm.ros2.types import TypeStore, default_store

__all__ = [
    "BagReader", "BagRecord", "BagWriter", "read_bag", "recorded_damage", "recorded_topics",
    "recorded_types", "STORAGE_SUFFIXES",
]

_log = logging.getLogger("rasm.ros2.bags")

STORAGE_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}


class BagRecord(NamedTuple):
    """One recorded message: its log time (ns since the epoch), topic and decoded content."""

    time_ns: int
    topic: str
    message: Any  # a dict; with BagReader(objects=) or (fields=) a message object or values


def storage_files(path: str | Path) -> list[Path]:
    """The storage files of a recording: the file itself, or a folder's files in order."""
    bag = Path(path)
    if not bag.exists():
        raise BagError(f"{bag}: no such bag folder or file")
    if bag.is_file():
        if bag.suffix not in STORAGE_SUFFIXES:
            raise BagError(
                f"{bag}: not a rosbag2 storage file (expected .mcap or .db3, or a bag folder)"
            )
        return [bag]
    listed = _listed_files(bag)
    files = listed if listed is not None else sorted(
        p for p in bag.iterdir() if p.suffix in STORAGE_SUFFIXES
    )
    if not files:
        raise BagError(f"{bag}: no .mcap or .db3 storage file in this folder")
    compressed = [f for f in files if f.suffix not in STORAGE_SUFFIXES]
    if compressed:
        raise BagError(
            f"{compressed[0]}: compressed storage files are not read; decompress the bag "
            "first (ros2 bag convert, or rosbags-convert)"
        )
    return files


def _listed_files(folder: Path) -> list[Path] | None:
    """The storage files ``metadata.yaml`` lists, or None without a readable list."""
    meta = folder / "metadata.yaml"
    if not meta.is_file():
        return None
    try:
        data = YAML(typ="safe").load(meta.read_text(encoding="utf-8"))
        names = data["rosbag2_bagfile_information"]["relative_file_paths"]
    except (OSError, UnicodeDecodeError, YAMLError, KeyError, TypeError) as exc:
        raise BagError(f"{meta}: not a rosbag2 metadata file ({exc})") from None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise BagError(f"{meta}: relative_file_paths is not a list of file names")
    files = [folder / name for name in names]
    missing = [f for f in files if not f.exists()]
    if missing:
        raise BagError(f"{meta} lists {missing[0].name}, which is not in the folder")
    return files


class BagReader:
    """Read a rosbag2 recording as :class:`BagRecord` items (iterate over the reader).

    ``topics`` limits the reading to those topics (default: all); a selected topic whose type
    cannot be decoded (no definition in the store or the bag) raises :class:`BagError`, while
    reading all topics leaves such a topic out (listed in :attr:`undecodable`, logged once):
    rosbag2's service-event topics, say. ``store`` is the type store (default: the standard
    interfaces); the bag's own definitions fill in the types it lacks. With ``objects``, each
    message is rosbags' message object instead of a dict (:meth:`MessageCodec.decode_object`).
    ``fields`` maps topics to field paths: a message of such a topic is the list of those
    fields' values instead (:func:`rasm.ros2.fieldread.field_reader`: read from the CDR
    without decoding the rest). :attr:`topics` maps every recorded topic to its type;
    :attr:`message_count` counts the messages of the selected topics.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        topics: Iterable[str] | None = None,
        store: TypeStore | None = None,
        objects: bool = False,
        fields: Mapping[str, Sequence[str]] | None = None,
    ) -> None:
        self.path = Path(path)
        self.objects = objects
        self.fields = dict(fields or {})
        self.store = store if store is not None else default_store()
        self.rejected = 0
        self._files = storage_files(self.path)
        self._wanted = None if topics is None else set(topics)
        self._reported: set[str] = set()
        self._damage: dict[tuple[str, str], Damage] = {}  # by file and place
        # per file and topic: messages that did not decode, the first and last log time
        self._undecoded: dict[tuple[str, str], list[int]] = {}
        self.topics: dict[str, str] = {}
        self.undecodable: dict[str, str] = {}  # topic -> why (reading all topics only)
        self.message_count = 0
        # (topic, type, hash) -> how its messages are decoded
        self._decoders: dict[tuple[str, str, str], Callable[[bytes], Any]] = {}
        for file in self._files:
            with _opened(file) as reader:
                self._scan(reader)
                self._note_damage(reader.damage)
        if self._wanted is not None:
            absent = sorted(self._wanted - set(self.topics))
            if absent:
                damaged = "; damaged: " + "; ".join(d.describe() for d in self.damage) if (
                    self.damage) else ""
                raise BagError(
                    f"{self.path}: no topic {absent[0]} in this recording (it has "
                    f"{', '.join(sorted(self.topics)) or 'no topics'}){damaged}"
                )

    @property
    def damage(self) -> list[Damage]:
        """What could not be read of the selected topics: damaged parts of the storage files
        (complete once the messages were read to the end) and messages that did not decode."""
        selected = set(self._wanted) if self._wanted is not None else None
        found = [d for d in self._damage.values()
                 if selected is None or d.concerns(selected)]
        for (file, topic), (count, first, last) in self._undecoded.items():
            found.append(Damage(file, f"{count:,} message{'s' if count != 1 else ''} on {topic}",
                                "not a valid message of its type (it does not decode)",
                                messages=count, start_ns=first, end_ns=last, topics=(topic,)))
        return found

    def _note_damage(self, damage: Iterable[Damage]) -> None:
        for d in damage:
            self._damage.setdefault((d.file, d.where), d)

    def _scan(self, reader: Reader) -> None:
        for connection in reader.connections:
            known = self.topics.setdefault(connection.topic, connection.msgtype)
            if not self._selects(connection.topic):
                continue
            if known != connection.msgtype:
                raise BagError(
                    f"{self.path}: topic {connection.topic} is recorded with two types, "
                    f"{known} and {connection.msgtype}"
                )
            try:
                self._decoder(connection)
            except BagError as exc:
                if self._wanted is not None:
                    raise
                self.undecodable[connection.topic] = str(exc)
                _log.warning("%s (the topic is not read)", exc)
                continue
            self.message_count += connection.msgcount

    def _selects(self, topic: str) -> bool:
        if self._wanted is None:
            return topic not in self.undecodable
        return topic in self._wanted

    def _decoder(self, connection: Connection) -> Callable[[bytes], Any]:
        key = (connection.topic, connection.msgtype, connection.digest or "")
        decoder = self._decoders.get(key)
        if decoder is not None:
            return decoder
        try:
            if connection.msgtype in self.store and (
                not connection.digest or connection.digest == self.store.type_hash(
                    connection.msgtype
                )
            ):
                store = self.store
            else:
                store = _recorded_store(connection)
            codec = store.codec(connection.msgtype)
            if connection.topic in self.fields:
                decoder = field_reader(store, connection.msgtype, self.fields[connection.topic])
            else:
                decoder = codec.decode_object if self.objects else codec.decode
        except (RosError, TypesysError, KeyError, ValueError) as exc:
            raise BagError(
                f"{self.path}: cannot decode topic {connection.topic} ({connection.msgtype}): "
                f"{exc}"
            ) from None
        self._decoders[key] = decoder
        return decoder

    def __iter__(self) -> Iterator[BagRecord]:
        streams = [self._records(file) for file in self._files]
        if len(streams) == 1:  # one storage file is in log-time order already
            return streams[0]
        return heapq.merge(*streams, key=lambda record: record.time_ns)

    def _records(self, file: Path) -> Iterator[BagRecord]:
        with _opened(file) as reader:
            try:
                connections = [c for c in reader.connections if self._selects(c.topic)]
                if not connections:
                    return
                for connection, time_ns, data in reader.messages(connections):
                    decode = self._decoders[
                        (connection.topic, connection.msgtype, connection.digest or "")
                    ]
                    try:
                        message = decode(data)
                    except MalformedMessage as exc:
                        self._reject(file, connection.topic, time_ns, str(exc))
                        continue
                    yield BagRecord(time_ns, connection.topic, message)
            finally:
                self._note_damage(reader.damage)

    def _reject(self, file: Path, topic: str, time_ns: int, reason: str) -> None:
        key = (str(file), topic)
        seen = self._undecoded.get(key)
        if seen is None:
            self._undecoded[key] = [1, time_ns, time_ns]
        elif time_ns > seen[2]:  # a second pass over the recording counts nothing twice
            seen[0] += 1
            seen[2] = time_ns
        self.rejected += 1
        if topic not in self._reported:
            self._reported.add(topic)
            _log.warning(
                "%s: skipped a message on %s at %d ns: %s (further ones on %s are only counted)",
                self.path, topic, time_ns, reason, topic,
            )


def recorded_topics(path: str | Path) -> dict[str, str]:
    """Every topic of a recording and its type, without looking at the types' definitions."""
    topics: dict[str, str] = {}
    for file in storage_files(path):
        with _opened(file) as reader:
            for connection in reader.connections:
                topics.setdefault(connection.topic, connection.msgtype)
    return topics


def recorded_damage(path: str | Path) -> list[Damage]:
    """What opening a recording's storage files already found damaged (reading its messages
    may find more: :attr:`BagReader.damage`)."""
    found: list[Damage] = []
    for file in storage_files(path):
        with _opened(file) as reader:
            found += reader.damage
    return found


def read_bag(
    path: str | Path, topics: Iterable[str] | None = None, store: TypeStore | None = None
) -> Iterator[BagRecord]:
    """``BagRecord(time_ns, topic, message)`` of every message of ``topics`` (default: all)."""
    return iter(BagReader(path, topics=topics, store=store))


class _opened:
    """One storage file, open for a ``with`` block, read with the checks of its format
    (:class:`_McapStorage`, :class:`_Db3Storage`); errors as BagError."""

    def __init__(self, file: Path) -> None:
        self.file = file
        self.storage: _McapStorage | _Db3Storage | None = None

    def __enter__(self) -> _McapStorage | _Db3Storage:
        kind = _McapStorage if self.file.suffix == ".mcap" else _Db3Storage
        try:
            self.storage = kind(self.file)
        except BagError:
            raise
        except (ReaderError, OSError, ValueError, KeyError, TypeError) as exc:
            raise BagError(f"{self.file}: cannot read this rosbag2 storage file: {exc}") from None
        except Exception as exc:  # the storage libraries' own errors (sqlite, mcap parsing)
            raise BagError(f"{self.file}: cannot read this rosbag2 storage file: {exc}") from None
        return self.storage

    def __exit__(self, *exc: object) -> None:
        if self.storage is not None:
            self.storage.close()


_Read = tuple[Connection, int, bytes]  # a message as a storage gives it: connection, time, data

_DEFINITION_FORMATS = {
    "ros2msg": MessageDefinitionFormat.MSG,
    "ros2idl": MessageDefinitionFormat.IDL,
    "omgidl": MessageDefinitionFormat.IDL,
}


class _McapStorage:
    """An MCAP storage file read by :class:`rasm.mcapfile.McapReader`, which checks every chunk
    it reads and reports what it cannot (:attr:`damage`), in the shape of a rosbags reader."""

    def __init__(self, file: Path) -> None:
        from rosbags.interfaces import ConnectionExtRosbag2, MessageDefinition
        from rosbags.rosbag2.metadata import parse_qos

        from rasm.mcapfile import McapError, McapReader

        try:
            self.reader = McapReader(file)
        except McapError as exc:
            raise BagError(f"{file}: cannot read this rosbag2 storage file: {exc}") from None
        if self.reader.profile != "ros2":
            self.reader.close()
            raise BagError(
                f"{file}: not a rosbag2 recording (its MCAP profile is "
                f"{self.reader.profile or 'empty'!r}, not 'ros2')"
            )
        self.connections: list[Connection] = []
        for channel in self.reader.channels.values():
            schema = self.reader.schemas.get(channel.schema_id)
            definition = MessageDefinition(
                _DEFINITION_FORMATS.get(schema.encoding, MessageDefinitionFormat.NONE)
                if schema else MessageDefinitionFormat.NONE,
                schema.data.decode("utf-8", "replace") if schema else "",
            )
            try:
                qos = parse_qos(channel.metadata.get("offered_qos_profiles", ""))
            except Exception:  # QoS are not read: a profile rosbags cannot parse is no loss
                qos = []
            self.connections.append(Connection(
                channel.id, channel.topic, schema.name if schema else "", definition, "",
                self.reader.counts.get(channel.id, 0),
                ConnectionExtRosbag2(channel.encoding, qos), self,
            ))

    @property
    def damage(self) -> list[Damage]:
        return self.reader.damage

    def messages(self, connections: Iterable[Connection]) -> Iterator[_Read]:
        by_id = {c.id: c for c in connections}
        for channel, time_ns, data in self.reader.messages(set(by_id)):
            yield by_id[channel], time_ns, data

    def close(self) -> None:
        self.reader.close()


class _Db3Storage:
    """A SQLite3 storage file read by rosbags, once SQLite's ``quick_check`` found it sound.
    A damaged one is salvaged first: every message row that can be read is copied into a
    temporary file (read by rosbags in its place), and the rows that cannot are reported as
    :attr:`damage` (rosbag2 numbers its messages 1, 2, 3, …: a missing number is a lost
    message), with the time range around them."""

    def __init__(self, file: Path) -> None:
        self.file = file
        self.damage: list[Damage] = []
        self._folder: str | None = None
        problem = _db3_problem(file)
        path = file
        if problem is not None:
            self._folder, path, self.damage = _salvage_db3(file, problem)
        try:
            self.reader = Reader(path)
            self.reader.open()
        except BaseException:
            self._remove()
            raise
        self.connections: list[Connection] = list(self.reader.connections)

    def messages(self, connections: Iterable[Connection]) -> Iterator[_Read]:
        return self.reader.messages(connections=list(connections))

    def close(self) -> None:
        try:
            if self.reader.is_open:
                self.reader.close()
        finally:
            self._remove()

    def _remove(self) -> None:
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None


def _db3_connect(file: Path) -> sqlite3.Connection:
    # immutable: read as it is, no lock, no journal (as rosbags reads it); writable_schema: a
    # table whose root page is past a cut end does not keep the others from being read
    db = sqlite3.connect(f"file:{quote(str(file.resolve()))}?mode=ro&immutable=1", uri=True)
    db.execute("PRAGMA writable_schema=ON")
    return db


def _db3_problem(file: Path) -> str | None:
    """What SQLite finds wrong with a storage file's pages (None: nothing)."""
    try:
        db = _db3_connect(file)
    except sqlite3.Error as exc:
        return str(exc)
    try:
        rows = db.execute("PRAGMA quick_check(5)").fetchall()
    except sqlite3.Error as exc:
        return str(exc)
    finally:
        db.close()
    found = [str(row[0]) for row in rows if row and row[0] != "ok"]
    if not found:
        return None
    first = found[0].splitlines()
    # quick_check's first line may only name the database ("*** in database main ***")
    text = next((line for line in first if not line.startswith("***")), first[0])
    return text if len(found) == 1 and len(first) <= 2 else f"{text}, …"


_BLOCK = 4096  # message rows read at once while salvaging
_EMPTY_BLOCKS = 4  # without a known last row: blocks of nothing read after which reading stops
_RUNS_REPORTED = 20  # runs of lost rows reported one by one (the rest in one)


def _salvage_db3(file: Path, problem: str) -> tuple[str, Path, list[Damage]]:
    """Copy what can be read of a damaged storage file into a temporary one: its tables as
    they are, its messages row by row around the damage. Returns the folder, the copy and
    the damage (runs of message rows that could not be read)."""
    folder = tempfile.mkdtemp(prefix="rasm-salvaged-")
    copy = Path(folder) / file.name
    try:
        source = _db3_connect(file)
        target = sqlite3.connect(copy)
        try:
            schema = source.execute(
                "SELECT type, name, sql FROM sqlite_master WHERE sql IS NOT NULL"
            ).fetchall()
            tables = [(name, sql) for kind, name, sql in schema
                      if kind == "table" and not name.startswith("sqlite_")]
            if "messages" not in {name for name, _ in tables}:
                raise BagError(f"{file}: cannot read this rosbag2 storage file: it is damaged "
                               f"({problem}) and its messages table cannot be found")
            for _, sql in tables:
                target.execute(sql)
            for name, _ in tables:
                if name != "messages":
                    _copy_table(source, target, name, file, problem)
            lost = _copy_messages(source, target)
            for kind, _, sql in schema:
                if kind == "index":
                    target.execute(sql)
            target.commit()
        except sqlite3.Error as exc:
            raise BagError(f"{file}: cannot read this rosbag2 storage file: it is damaged "
                           f"({problem}) where its tables are described ({exc})") from None
        finally:
            source.close()
            target.close()
        damage = _lost_rows(file, problem, lost)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return folder, copy, damage


def _copy_table(source: sqlite3.Connection, target: sqlite3.Connection, name: str,
                file: Path, problem: str) -> None:
    try:
        rows = source.execute(f'SELECT * FROM "{name}"').fetchall()
    except sqlite3.Error as exc:
        raise BagError(f"{file}: cannot read this rosbag2 storage file: it is damaged "
                       f"({problem}) and its table {name} cannot be read ({exc})") from None
    if rows:
        marks = ", ".join("?" * len(rows[0]))
        target.executemany(f'INSERT INTO "{name}" VALUES ({marks})', rows)


def _copy_messages(source: sqlite3.Connection, target: sqlite3.Connection) -> _Lost:
    """Copy every message row that can be read, by id (rosbag2 numbers them 1, 2, 3, …, so a
    missing number is a lost message); returns what could not be read."""
    columns = [row[1] for row in source.execute("PRAGMA table_info(messages)")]
    insert = f"INSERT OR IGNORE INTO messages VALUES ({', '.join('?' * len(columns))})"
    timestamp = columns.index("timestamp")
    try:
        (top,) = source.execute("SELECT max(id) FROM messages").fetchone()
        known = True
    except sqlite3.Error:  # the last rows cannot be reached: read on until nothing comes
        top, known = None, False
    read: dict[int, int] = {}  # id -> log time, of the rows read
    unreadable = 0  # the highest id whose row SQLite could not read

    def take(low: int, high: int) -> int:
        nonlocal unreadable
        try:
            rows = source.execute("SELECT * FROM messages WHERE id BETWEEN ? AND ?",
                                  (low, high)).fetchall()
        except sqlite3.Error:
            if low == high:
                unreadable = max(unreadable, low)
                return 0
            middle = (low + high) // 2
            return take(low, middle) + take(middle + 1, high)
        target.executemany(insert, rows)
        for row in rows:
            read[row[0]] = row[timestamp]
        return len(rows)

    low, empty = 1, 0
    while (low <= top) if known else (empty < _EMPTY_BLOCKS):
        high = low + _BLOCK - 1
        if known:
            high = min(high, top)
        empty = 0 if take(low, high) else empty + 1
        low = high + 1
    last = top if known else max(read, default=0)
    runs: list[tuple[int, int, int | None, int | None]] = []
    first: int | None = None
    for number in range(1, last + 2):
        if number <= last and number not in read:
            if first is None:
                first = number
        elif first is not None:
            runs.append((first, number - 1, read.get(first - 1), read.get(number)))
            first = None
    # rows past the last one read that SQLite could not read: how many, nobody knows
    tail = (last + 1, read.get(last)) if not known and unreadable > last else None
    return _Lost(runs, tail)


class _Lost(NamedTuple):
    runs: list[tuple[int, int, int | None, int | None]]  # first id, last id, time before, after
    tail: tuple[int, int | None] | None  # the first id of an unreadable end, the time before


def _lost_rows(file: Path, problem: str, lost: _Lost) -> list[Damage]:
    reason = f"SQLite reports the file damaged ({problem})"
    if not lost.runs and lost.tail is None:
        # SQLite keeps no checksums: a row that reads may still hold bytes the damage changed
        return [Damage(str(file), "its pages", f"{reason}; every message row was read, but "
                       "the values on the damaged pages may be wrong", messages=0)]
    shown = lost.runs[:_RUNS_REPORTED]
    damage = [
        Damage(str(file), f"message rows {first:,} to {last:,}" if first != last
               else f"message row {first:,}", f"{reason}: they cannot be read",
               messages=last - first + 1, start_ns=before, end_ns=after)
        for first, last, before, after in shown
    ]
    rest = lost.runs[_RUNS_REPORTED:]
    if rest:
        damage.append(Damage(
            str(file), f"{len(rest):,} more runs of message rows from row {rest[0][0]:,}",
            f"{reason}: they cannot be read",
            messages=sum(last - first + 1 for first, last, _, _ in rest),
            start_ns=rest[0][2], end_ns=rest[-1][3],
        ))
    if lost.tail is not None:
        first, before = lost.tail
        damage.append(Damage(str(file), f"the message rows from {first:,} on",
                             f"{reason}: they cannot be read", start_ns=before))
    return damage


def _recorded_store(connection: Connection) -> TypeStore:
    """A type store holding the definition the bag recorded for ``connection``'s type."""
    store = TypeStore("empty")
    store.register(_recorded_definitions(connection))
    digest = connection.digest
    if digest and digest.startswith("RIHS01_") and store.type_hash(connection.msgtype) != digest:
        raise BagError(
            f"the definition recorded for {connection.msgtype} does not match its recorded "
            f"type hash {digest}"
        )
    return store


def _recorded_definitions(connection: Connection) -> dict[str, tuple]:
    """The rosbags definitions of ``connection``'s type (and the types it uses) the bag
    recorded."""
    definition = connection.msgdef
    if definition.format == MessageDefinitionFormat.MSG and definition.data:
        return get_types_from_msg(definition.data, connection.msgtype)
    if definition.format == MessageDefinitionFormat.IDL and definition.data:
        types = {}
        separator = "=" * 80 + "\n"
        for part in definition.data.split(separator):
            text = part.split("\n", 1)[1] if part.startswith("IDL: ") else part
            if text.strip():
                types.update(get_types_from_idl(text))
        return types
    raise BagError(
        f"the bag has no definition of {connection.msgtype}, and the type store does not "
        "hold it (add the package's .msg files)"
    )


def recorded_types(path: str | Path, store: TypeStore) -> list[str]:
    """Add to ``store`` the types a recording defines and the store lacks (what a topic map
    may then name); returns their names. A definition that does not parse is left out: reading
    its topic reports it."""
    added = []
    for file in storage_files(path):
        with _opened(file) as reader:
            for connection in reader.connections:
                if connection.msgtype in store:
                    continue
                try:
                    definitions = _recorded_definitions(connection)
                except (BagError, TypesysError, KeyError, ValueError):
                    continue
                store.register(
                    {name: d for name, d in definitions.items() if name not in store}
                )
                added.append(connection.msgtype)
    return added


class BagWriter:
    """Write a rosbag2 recording (a new bag folder) from message dicts.

    ``storage`` is ``"mcap"`` (default) or ``"sqlite3"``. Declare each topic with
    :meth:`add_topic`, then :meth:`write` messages; :meth:`close` (or the ``with`` block)
    finishes the folder with its ``metadata.yaml``. The bag records each type's definition and
    RIHS01 hash, so any rosbag2 reader decodes it.
    """

    def __init__(
        self, path: str | Path, *, storage: str = "mcap", store: TypeStore | None = None
    ) -> None:
        plugins = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
        if storage not in plugins:
            raise BagError(f"unknown bag storage {storage!r}; use mcap or sqlite3")
        self.path = Path(path)
        self.store = store if store is not None else default_store()
        try:
            self._writer = Writer(self.path, version=9, storage_plugin=plugins[storage])
            self._writer.open()
        except (WriterError, OSError) as exc:
            raise BagError(f"{self.path}: cannot create a bag here: {exc}") from None
        self._topics: dict[str, tuple[Connection, MessageCodec]] = {}

    def add_topic(self, topic: str, typename: str) -> None:
        """Declare ``topic`` with its message type (once per topic)."""
        if topic in self._topics:
            raise BagError(f"{self.path}: topic {topic} is already in this bag")
        codec = self.store.codec(typename)
        connection = self._writer.add_connection(
            topic, codec.typename, typestore=self.store.rosbags
        )
        self._topics[topic] = (connection, codec)

    def write(self, topic: str, time_ns: int, message: Mapping[str, Any]) -> None:
        """Record ``message`` (a dict; unset fields are zero) on ``topic`` at ``time_ns``."""
        found = self._topics.get(topic)
        if found is None:
            raise BagError(f"{self.path}: topic {topic} was not added (call add_topic first)")
        connection, codec = found
        self._writer.write(connection, time_ns, codec.encode(message))

    def close(self) -> None:
        """Finish the bag (writes ``metadata.yaml``); idempotent."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            writer.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
