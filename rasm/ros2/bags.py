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
"""

from __future__ import annotations

import heapq
import logging
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.rosbag2 import Reader, ReaderError, StoragePlugin, Writer, WriterError
from rosbags.typesys import TypesysError, get_types_from_idl, get_types_from_msg
from ruamel.yaml import YAML, YAMLError

from rasm.ros2.codec import MessageCodec
from rasm.ros2.errors import BagError, MalformedMessage, RosError
from rasm.ros2.fieldread import field_reader
from rasm.ros2.types import TypeStore, default_store

__all__ = [
    "BagReader", "BagRecord", "BagWriter", "read_bag", "recorded_topics", "recorded_types",
    "STORAGE_SUFFIXES",
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
        self.topics: dict[str, str] = {}
        self.undecodable: dict[str, str] = {}  # topic -> why (reading all topics only)
        self.message_count = 0
        # (topic, type, hash) -> how its messages are decoded
        self._decoders: dict[tuple[str, str, str], Callable[[bytes], Any]] = {}
        for file in self._files:
            with _opened(file) as reader:
                self._scan(reader)
        if self._wanted is not None:
            absent = sorted(self._wanted - set(self.topics))
            if absent:
                raise BagError(
                    f"{self.path}: no topic {absent[0]} in this recording (it has "
                    f"{', '.join(sorted(self.topics)) or 'no topics'})"
                )

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
            connections = [c for c in reader.connections if self._selects(c.topic)]
            if not connections:
                return
            for connection, time_ns, data in reader.messages(connections=connections):
                decode = self._decoders[
                    (connection.topic, connection.msgtype, connection.digest or "")
                ]
                try:
                    message = decode(data)
                except MalformedMessage as exc:
                    self._reject(connection.topic, time_ns, str(exc))
                    continue
                yield BagRecord(time_ns, connection.topic, message)

    def _reject(self, topic: str, time_ns: int, reason: str) -> None:
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


def read_bag(
    path: str | Path, topics: Iterable[str] | None = None, store: TypeStore | None = None
) -> Iterator[BagRecord]:
    """``BagRecord(time_ns, topic, message)`` of every message of ``topics`` (default: all)."""
    return iter(BagReader(path, topics=topics, store=store))


class _opened:
    """A rosbags reader of one storage file, open for a ``with`` block; errors as BagError."""

    def __init__(self, file: Path) -> None:
        self.file = file
        self.reader: Reader | None = None

    def __enter__(self) -> Reader:
        try:
            self.reader = Reader(self.file)
            self.reader.open()
        except (ReaderError, OSError, ValueError, KeyError, TypeError) as exc:
            raise BagError(f"{self.file}: cannot read this rosbag2 storage file: {exc}") from None
        except Exception as exc:  # the storage libraries' own errors (sqlite, mcap parsing)
            raise BagError(f"{self.file}: cannot read this rosbag2 storage file: {exc}") from None
        return self.reader

    def __exit__(self, *exc: object) -> None:
        if self.reader is not None and self.reader.is_open:
            self.reader.close()


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
