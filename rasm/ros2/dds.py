"""ROS 2 over DDS with Cyclone DDS, named as ROS 2's DDS middlewares name things.

- A topic ``/odom`` is the DDS topic ``rt/odom``; its type is ``nav_msgs::msg::dds_::Odometry_``,
  a final struct with the message's fields (built from the type store), in XCDR1 (plain CDR).
- Endpoints carry ``typehash=RIHS01_...;`` in their USER_DATA, as ROS 2 (Iron and later) does;
  samples from a publisher that announces another hash are rejected as ``wrong_hash``.
- A publisher of another type on one of our topics is refused: discovery sees it (also one
  that came before our reader) and counts it once as ``type_conflict`` (or ``unknown_type``);
  should Cyclone match it (a type of the same shape: Cyclone matches types by structure), its
  samples are refused and counted too.
- QoS: reliability, durability, history and depth map to the DDS policies of the same names.
- Receiving: no listener, so Cyclone's threads never run Python (a listener waiting for the
  GIL while a write holding it waited for the listener deadlocked the process). One taking
  thread per transport waits on a waitset, GIL released, takes what the readers hold and
  hands it to the dispatcher (:mod:`rasm.ros2.transport`).
- Sizes: a sample over ``max_payload`` is refused unread; in a domain rasm makes, Cyclone
  itself drops it before reassembling it (``Internal/MaxSampleSize``, :class:`_Domains`).
- The ROS graph: as rmw_cyclonedds does, the participant publishes its node (namespace, name)
  and the GIDs (DDS GUIDs) of its readers and writers as an
  ``rmw_dds_common/msg/ParticipantEntitiesInfo`` on ``ros_discovery_info`` (reliable,
  transient local, keep last 1), again whenever they change; so ``ros2 node list`` and
  ``ros2 node info`` on the DDS network show rasm's node.

The network is configured the standard Cyclone way, by ``CYCLONEDDS_URI`` (or ``config=``).
On loopback only, for tests::

    <CycloneDDS><Domain id="any"><General><Interfaces>
      <NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast></General>
      <Discovery><Peers><Peer address="127.0.0.1"/></Peers>
      <ParticipantIndex>auto</ParticipantIndex></Discovery></Domain></CycloneDDS>
"""

from __future__ import annotations

import itertools
import logging
import os
import re
import threading
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

from cyclonedds._clayer import ddspy_take, ddspy_write  # raw CDR in and out (see _wire_send)
from cyclonedds.builtin import (
    BuiltinDataReader,
    BuiltinTopicDcpsParticipant,
    BuiltinTopicDcpsPublication,
)
from cyclonedds.core import (
    DDSException,
    GuardCondition,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl import types as idl
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys.base import normalize_fieldname

from rasm.comm.envelope import MAX_PAYLOAD
from rasm.errors import CommError
from rasm.ros2.qos import QosProfile
from rasm.ros2.transport import (
    RosTopic,
    RosTransport,
    merge_settings,
    node_of,
    oversize,
    url_settings,
)
from rasm.ros2.types import (
    PLACEHOLDER_FIELD,
    WSTRING_TYPE,
    FieldType,
    TypeStore,
    ros_type_name,
)

__all__ = ["DdsTransport", "parse_dds_url", "dds_topic_name", "idl_struct"]

_log = logging.getLogger("rasm.ros2.dds")

ACCEPTED_FORM = "'dds://' or 'dds://?domain=N', optionally with &max_payload=BYTES"
_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
_TAKE_BATCH = 64
_WAIT = duration(seconds=1)  # the taking thread's longest sleep; closing wakes it at once
_MAX_SEEN = 10_000  # publications remembered from discovery
_TYPEHASH = re.compile(rb"typehash=([^;]*);")
GRAPH_TOPIC = "ros_discovery_info"  # where rmw_cyclonedds publishes each participant's nodes
GRAPH_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"

_PRIMITIVES: dict[str, Any] = {
    "bool": bool, "byte": idl.byte, "char": idl.uint8, "uint8": idl.uint8, "int8": idl.int8,
    "uint16": idl.uint16, "int16": idl.int16, "uint32": idl.uint32, "int32": idl.int32,
    "uint64": idl.uint64, "int64": idl.int64, "float32": idl.float32, "float64": idl.float64,
}
# the IDL classes built so far, by type name and hash (a hash names one definition)
_IDL_CLASSES: dict[tuple[str, str], type[IdlStruct]] = {}


@dataclass
class _MadeDomain:
    domain: Domain
    cap: int  # Cyclone's MaxSampleSize in it
    config: str | None  # the config= it was made with
    users: int = 0  # the transports on it


class _Domains:
    """The Cyclone domains rasm's transports made in this process, by id: each made with a
    configuration that caps a sample's size (Cyclone's ``Internal/MaxSampleSize``), so that
    Cyclone drops a bigger one as its first fragment arrives, before it holds any of it; the
    rest of the configuration is ``config=`` or ``CYCLONEDDS_URI``, read after the cap (what
    it sets wins). A domain goes with the last transport on it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._made: dict[int, _MadeDomain] = {}

    def join(self, domain: int, config: str | None, max_payload: int) -> bool:
        """Count one more transport on ``domain``, making the domain if need be; False when
        the process already has the domain from elsewhere (its configuration stands)."""
        cap = max(max_payload + -max_payload % 4, MAX_PAYLOAD)  # padded; discovery fits
        with self._lock:
            made = self._made.get(domain)
            if made is None:
                text = ",".join(part for part in (
                    _SAMPLE_CAP.format(cap), config or os.environ.get("CYCLONEDDS_URI", "")
                ) if part)
                try:
                    made = self._made[domain] = _MadeDomain(Domain(domain, text), cap, config)
                except DDSException as exc:
                    if exc.code != _ALREADY_THERE or config is not None:
                        raise
                    return False  # another part of this process joined it first
            elif made.config != config or cap > made.cap:
                raise CommError(
                    f"DDS domain {domain} is already open in this process with another "
                    "configuration or a smaller max_payload; give the transports on one domain "
                    "the same config= and max_payload"
                )
            made.users += 1
            return True

    def leave(self, domain: int) -> None:
        """One transport less on ``domain``; the last one deletes it."""
        with self._lock:
            made = self._made[domain]
            made.users -= 1
            if made.users == 0:
                del self._made[domain]
                made.domain.__del__()


_SAMPLE_CAP = (
    '<CycloneDDS><Domain id="any"><Internal><MaxSampleSize>{}B</MaxSampleSize></Internal>'
    "</Domain></CycloneDDS>"
)
_ALREADY_THERE = -4  # DDS_RETCODE_PRECONDITION_NOT_MET: the domain exists
_DOMAINS = _Domains()


def parse_dds_url(url: str) -> dict[str, int]:
    """The settings of a ``dds://`` URL's query (``domain``, ``max_payload``: those it names);
    :class:`CommError` for anything else."""
    def bad(why: str) -> CommError:
        return CommError(f"bad transport URL {url!r}: {why}; expected {ACCEPTED_FORM}")

    parts = urlsplit(url.strip()) if isinstance(url, str) else None
    if parts is None or parts.scheme != "dds":
        raise bad("not a dds:// URL")
    if parts.netloc or parts.path not in ("", "/") or parts.fragment:
        raise bad("a DDS domain has no host, path or fragment (the network is set by "
                  "CYCLONEDDS_URI)")
    return url_settings(parts.query, url, bad)


def dds_topic_name(topic: str) -> str:
    """The DDS topic of a ROS topic: ``/odom`` -> ``rt/odom``."""
    return "rt" + topic


def idl_struct(store: TypeStore, typename: str) -> type[IdlStruct]:
    """Cyclone's Python type for a message type, named ``pkg::msg::dds_::Name_``."""
    codec = store.codec(typename)
    key = (codec.typename, codec.type_hash)
    if key not in _IDL_CLASSES:
        fields = {
            normalize_fieldname(name): _idl_type(store, ftype)
            for name, ftype in store.fields(codec.typename).items()
        } or {PLACEHOLDER_FIELD: idl.uint8}
        _IDL_CLASSES[key] = make_idl_struct(
            codec.typename.replace("/", "_"), codec.dds_name, fields
        )
    return _IDL_CLASSES[key]


def _idl_type(store: TypeStore, ftype: FieldType) -> Any:
    if ftype.is_message:
        element = idl_struct(store, ftype.base)
    elif ftype.base == "wstring":  # the same CDR as a struct of one uint16 sequence
        element = idl_struct(store, WSTRING_TYPE)
    elif ftype.base == "string":
        element = idl.bounded_str[ftype.string_bound] if ftype.string_bound else str
    else:
        element = _PRIMITIVES[ftype.base]
    if ftype.array == "fixed":
        return idl.array[element, ftype.length]
    if ftype.array == "sequence":
        return idl.sequence[element, ftype.length] if ftype.length else idl.sequence[element]
    return element


def _qos(profile: QosProfile, type_hash: str) -> Qos:
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
        if profile.reliability == "reliable" else Policy.Reliability.BestEffort,
        Policy.Durability.TransientLocal
        if profile.durability == "transient_local" else Policy.Durability.Volatile,
        Policy.History.KeepAll if profile.keeps_all else Policy.History.KeepLast(profile.depth),
        Policy.DataRepresentation(use_cdrv0_representation=True),  # plain CDR, as ROS 2
        Policy.Userdata(f"typehash={type_hash};".encode()),
    )


_GRAPH_QOS = Qos(
    Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
    Policy.Durability.TransientLocal,
    Policy.History.KeepLast(1),
    Policy.DataRepresentation(use_cdrv0_representation=True),
)


# rasm's own reader of the graph keeps every participant's latest announcement until it is
# read (a keyless topic is one instance: keep last 1 would keep one participant's alone)
_GRAPH_READER_QOS = Qos(
    Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
    Policy.Durability.TransientLocal,
    Policy.History.KeepLast(256),
    Policy.DataRepresentation(use_cdrv0_representation=True),
)
_GUID = 16  # bytes of a DDS GUID, as a GID starts with it


class _DdsGraph:
    """The ROS graph over DDS, read when asked (never from a listener): each participant's
    nodes and their writers' GUIDs from ``ros_discovery_info``, and which participants are
    still there from DDS discovery."""

    def __init__(self, announcements: DataReader, participants: BuiltinDataReader) -> None:
        self._announcements = announcements
        self._participants = participants
        self._lock = threading.Lock()
        self._alive: set[bytes] = set()  # participant GUIDs
        self._nodes: dict[bytes, list[tuple[str, set[bytes]]]] = {}  # participant -> nodes

    def _refresh(self) -> None:
        while samples := self._participants.take(_TAKE_BATCH):
            for sample in samples:
                key = sample.key.bytes
                if sample.sample_info.instance_state == InstanceState.Alive:
                    self._alive.add(key)
                else:
                    self._alive.discard(key)
                    self._nodes.pop(key, None)
        while samples := self._announcements.take(_TAKE_BATCH):
            for sample in samples:
                if not getattr(sample, "gid", None) or len(self._nodes) > _MAX_SEEN:
                    continue
                self._nodes[bytes(sample.gid.data)[:_GUID]] = [
                    (node_of(n.node_namespace, n.node_name),
                     {bytes(g.data)[:_GUID] for g in n.writer_gid_seq})
                    for n in sample.node_entities_info_seq
                ]

    def alive(self, node: str) -> bool:
        with self._lock:
            self._refresh()
            return any(
                name == node
                for participant in self._alive
                for name, _ in self._nodes.get(participant, ())
            )

    def writer_node(self, guid: bytes) -> str | None:
        """The node whose participant announces writer ``guid`` and is still there."""
        with self._lock:
            self._refresh()
            for participant in self._alive:
                for name, writers in self._nodes.get(participant, ()):
                    if guid[:_GUID] in writers:
                        return name
        return None


class DdsTransport(RosTransport):
    """ROS 2 topics over Cyclone DDS (see the module docstring).

    ``url`` is ``dds://`` or ``dds://?domain=N``, optionally with ``&max_payload=BYTES``.
    ``config`` is a Cyclone XML configuration (or a ``file://`` URL of one) for this domain;
    without it Cyclone reads ``CYCLONEDDS_URI``.
    The other keywords are :class:`~rasm.ros2.transport.RosTransport`'s. Its own samples come
    back to its own readers with its writers' handles, so it knows them.
    """

    tells_own_messages = True

    def __init__(
        self, url: str = "dds://", *, config: str | None = None, domain: int | None = None,
        max_payload: int | None = None, **options: Any,
    ) -> None:
        settings = {"domain": domain, "max_payload": max_payload}
        super().__init__(**merge_settings(url, parse_dds_url(url), settings), **options)
        self.url = url
        self.config = config
        self._joined = False  # whether _DOMAINS counts this transport as a user of its domain
        self._participant: DomainParticipant | None = None
        self._dds_topics: dict[str, Topic] = {}
        self._writers: dict[str, DataWriter] = {}
        # topic -> (declared topic, reader): replaced whole, never changed in place, as the
        # taking thread reads it while another subscribes
        self._reading: dict[str, tuple[RosTopic, DataReader]] = {}
        self._conditions: dict[str, ReadCondition] = {}
        self._fresh: deque[str] = deque()  # topics whose reader the taking thread has not seen
        self._waitset: WaitSet | None = None
        self._wake: GuardCondition | None = None  # wakes the taking thread
        self._stopping = threading.Event()
        self._taker: threading.Thread | None = None
        # publication handle -> (reason, why) its samples are refused, or None: fine
        self._publications: dict[int, tuple[str, str] | None] = {}
        self._foreign: set[Any] = set()  # publications of another type already counted
        # DDS topic -> {publication key: type name}: what discovery saw, also before we read
        self._seen: dict[str, dict[Any, str]] = {}
        self._discovery: BuiltinDataReader | None = None
        # own writers by handle: the numbers of the messages each sent, and of those back here
        self._own_writers: dict[int, Iterator[int]] = {}
        self._own_back: dict[int, int] = {}
        self._graph: DataWriter | None = None
        self._graph_view: _DdsGraph | None = None

    @property
    def participant(self) -> DomainParticipant | None:
        """The transport's DDS participant (None until connected): service and action
        clients (:mod:`rasm.ros2.calls`) make their readers and writers in it."""
        return self._participant

    # -- the wire -------------------------------------------------------------------------------
    def _open_wire(self) -> None:
        try:
            self._joined = _DOMAINS.join(self.domain, self.config, self.max_payload)
            self._participant = DomainParticipant(self.domain)
            self._discovery = BuiltinDataReader(self._participant, BuiltinTopicDcpsPublication)
            self._waitset = WaitSet(self._participant)
            self._wake = GuardCondition(self._participant)
            self._waitset.attach(self._wake)
            self._waitset.attach(ReadCondition(self._discovery, _ANY_SAMPLE))
            if GRAPH_TYPE in self.store:
                graph = Topic(self._participant, GRAPH_TOPIC, idl_struct(self.store, GRAPH_TYPE))
                self._graph = DataWriter(self._participant, graph, qos=_GRAPH_QOS)
                self._graph_view = _DdsGraph(
                    DataReader(self._participant, graph, qos=_GRAPH_READER_QOS),
                    BuiltinDataReader(self._participant, BuiltinTopicDcpsParticipant),
                )
                self._announce()
        except DDSException as exc:
            self._delete_all()
            raise CommError(
                f"could not join DDS domain {self.domain}: {exc} (check CYCLONEDDS_URI)"
            ) from None
        self._taker = threading.Thread(
            target=self._take_loop, name=f"rasm-dds-{self.url}", daemon=True
        )
        self._taker.start()

    def _close_wire(self) -> None:
        self._stopping.set()
        taker = self._taker
        if taker is not None:
            if self._wake is not None:
                self._wake.set(True)
            taker.join(timeout=5.0)  # it never waits for a callback: it ends within _WAIT
        self._delete_all()

    def _delete_all(self) -> None:
        # Cyclone deletes an entity when its Python object is collected; delete the participant
        # (and with it every reader, writer and topic) now, so that peers see us leave at once.
        participant = self._participant
        self._reading = {}
        self._conditions.clear()
        self._writers.clear()
        self._dds_topics.clear()
        self._discovery = self._participant = self._graph = None
        self._graph_view = None
        self._waitset = self._wake = None
        if participant is not None:
            participant.__del__()
        if self._joined:
            self._joined = False
            _DOMAINS.leave(self.domain)

    def _dds_topic(self, topic: RosTopic) -> Topic:
        found = self._dds_topics.get(topic.name)
        if found is None:
            found = self._dds_topics[topic.name] = Topic(
                self._participant, dds_topic_name(topic.name),
                idl_struct(self.store, topic.typename),
            )
        return found

    def _wire_publisher(self, topic: RosTopic) -> DataWriter:
        writer = self._writers.get(topic.name)
        if writer is None:
            writer = self._writers[topic.name] = DataWriter(
                self._participant, self._dds_topic(topic),
                qos=_qos(topic.qos, topic.codec.type_hash),
            )
            # readers see the handle unsigned; Python's binding gives it signed
            self._own_writers[writer.instance_handle % 2**64] = itertools.count(1)
            self._announce()
        return writer

    def _wire_size(self, data: bytes) -> int:
        return len(data) + -len(data) % 4  # padded, as _wire_send sends it

    def _wire_send(self, topic: RosTopic, data: bytes) -> None:
        writer = self._writers.get(topic.name) or self._wire_publisher(topic)
        # Cyclone's typed write() would re-encode a Python object; the codec's CDR goes as is,
        # padded to a multiple of 4 bytes as Cyclone's own serializer pads it.
        padded = data + b"\0" * (-len(data) % 4)
        handle = writer.instance_handle % 2**64
        self._own_sent(f"{handle}.{next(self._own_writers[handle])}", topic.name)
        result = ddspy_write(writer._ref, padded)
        if result < 0:
            raise CommError(f"{self.url}: could not publish on {topic.name} (DDS error {result})")

    def _wire_matched(self, topic: RosTopic, publisher: DataWriter) -> bool:
        return bool(publisher.get_matched_subscriptions())

    def _in_use(self, topic: str) -> bool:
        return topic in self._writers

    def _wire_subscribe(self, topic: RosTopic) -> None:
        if topic.name in self._reading:
            return
        assert self._waitset is not None and self._wake is not None
        reader = DataReader(
            self._participant, self._dds_topic(topic), qos=_qos(topic.qos, topic.codec.type_hash)
        )
        # no listener: Cyclone's threads never run Python; the condition wakes the taking thread
        # while the reader holds samples (also those that came while it was being made)
        condition = self._conditions[topic.name] = ReadCondition(reader, _ANY_SAMPLE)
        self._waitset.attach(condition)
        self._reading = {**self._reading, topic.name: (topic, reader)}
        self._fresh.append(topic.name)  # publishers discovered before it are judged there
        self._wake.set(True)
        self._announce()

    def _wire_unsubscribe(self, topic: RosTopic) -> None:
        entry = self._reading.get(topic.name)
        if entry is None:
            return
        self._reading = {k: v for k, v in self._reading.items() if k != topic.name}
        condition = self._conditions.pop(topic.name)
        if self._waitset is not None:
            self._waitset.detach(condition)
        entry[1].__del__()  # as in _delete_all: stop receiving now, not at collection
        self._announce()

    def _announce(self) -> None:
        """Publish this participant's node and its readers' and writers' GIDs on
        ``ros_discovery_info``, as rmw_cyclonedds does."""
        if self._graph is None or self._participant is None:
            return
        codec = self.store.codec(GRAPH_TYPE)
        size = self.store.fields("rmw_dds_common/msg/Gid")["data"].length  # 16; Humble: 24

        def gid(entity: Any) -> dict[str, list[int]]:
            data = entity.guid.bytes  # the 16-byte DDS GUID, as rmw_cyclonedds takes it
            return {"data": list(data.ljust(size, b"\0"))}

        info = {
            "gid": gid(self._participant),
            "node_entities_info_seq": [{
                "node_namespace": self.namespace,
                "node_name": self.node_name,
                # copies: another thread may add a reader or writer meanwhile
                "reader_gid_seq": [gid(reader) for _, reader in self._reading.values()],
                "writer_gid_seq": [gid(w) for w in list(self._writers.values())],
            }],
        }
        data = codec.encode(info)
        if ddspy_write(self._graph._ref, data + b"\0" * (-len(data) % 4)) < 0:
            _log.warning("could not publish rasm's node on %s", GRAPH_TOPIC)

    # -- receiving (on the taking thread; never raises) -----------------------------------------
    def _take_loop(self) -> None:
        """Wait (GIL released) until a reader holds samples, take them all, again, until the
        transport closes. The only thread that takes from the readers and reads discovery."""
        waitset, wake, stopping = self._waitset, self._wake, self._stopping
        assert waitset is not None and wake is not None
        while not stopping.is_set():
            try:
                waitset.wait(_WAIT)
                wake.take()  # reset: it only wakes this thread (closing, a new reader)
                while self._fresh:
                    self._judge_seen(self._fresh.popleft())
                self._take_publications()
                for topic, reader in self._reading.values():
                    self._take_samples(topic, reader)
            except Exception:
                if stopping.is_set():
                    return
                _log.exception("error receiving DDS data")
                stopping.wait(0.1)  # not a hot loop should the error repeat

    def _take_samples(self, topic: RosTopic, reader: DataReader) -> None:
        """Hand what waits in ``reader`` to the dispatcher; count what is refused."""
        limit = self.max_payload
        while True:
            samples = ddspy_take(reader._ref, _ANY_SAMPLE, _TAKE_BATCH)
            if isinstance(samples, int) or not samples:
                return  # empty, or the reader is gone (an error code)
            for data, info in samples:
                if not info.valid_data:
                    continue  # a writer left or disposed: no message
                handle = info.publication_handle
                uid = self._own_uid(handle)
                refused = self._publication_check(topic, reader, handle)
                if refused is not None:
                    self._reject(topic.name, *refused)
                elif len(data) > limit:
                    self._reject(topic.name, *oversize(len(data), limit))
                else:
                    self._received(topic, data, uid, info.source_timestamp / 1e9)
            if len(samples) < _TAKE_BATCH:
                return

    def _sent_here(self, uid: str | None) -> bool:
        return uid is not None  # only this participant's samples get a uid (_own_uid)

    def _own_uid(self, handle: int) -> str | None:
        """A sample's uid if one of this participant's writers sent it: the writer's handle
        and the sample's number (a reliable writer's samples reach a local reader in order);
        None for another participant's."""
        if handle not in self._own_writers:
            return None
        number = self._own_back[handle] = self._own_back.get(handle, 0) + 1
        return f"{handle}.{number}"

    def node_alive(self, node: str) -> bool:
        """Whether ROS node ``node``'s participant announces it on ``ros_discovery_info`` and
        is still there (DDS discovery: at once when it leaves, after its lease when it dies)."""
        graph = self._graph_view
        return graph is not None and graph.alive(node)

    def _publication_check(
        self, topic: RosTopic, reader: DataReader, handle: int
    ) -> tuple[str, str] | None:
        """None if samples of publication ``handle`` may be delivered, else the reason and why
        not: its type (:meth:`_type_check`) and, on a restricted topic, its node."""
        refused = self._type_check(topic, reader, handle)
        node = self._restricted.get(topic.name)
        if refused is None and node is not None:
            try:
                guid = reader.get_matched_publication_data(handle).key.bytes
            except (DDSException, AttributeError):
                guid = None
            graph = self._graph_view
            sender = graph.writer_node(guid) if graph is not None and guid else None
            if sender != node:
                who = sender or "a writer no node in the graph announces"
                return "foreign_publisher", (
                    f"published by {who}, not by {node} (its declared publisher)"
                )
        return refused

    def _type_check(
        self, topic: RosTopic, reader: DataReader, handle: int
    ) -> tuple[str, str] | None:
        """None if samples of publication ``handle`` may be delivered, else the reason and why
        not. A writer of another type name can match when its type has the same shape (Cyclone
        matches by XTypes assignability): it is refused all the same."""
        if handle in self._publications:
            return self._publications[handle]
        refused = None
        try:
            endpoint = reader.get_matched_publication_data(handle)
        except DDSException:
            endpoint = None
        if endpoint is not None and endpoint.type_name != topic.codec.dds_name:
            refused = self._other_type(topic, endpoint.type_name)
        elif endpoint is not None:
            qos = endpoint.qos
            userdata = qos[Policy.Userdata] if qos is not None and Policy.Userdata in qos else None
            found = _TYPEHASH.search(userdata.data) if userdata is not None else None
            announced = found.group(1).decode("ascii", "replace") if found else None
            if announced and announced != topic.codec.type_hash:
                refused = "wrong_hash", (
                    f"its publisher announces type hash {announced[:80]}, not "
                    f"{topic.codec.type_hash} ({topic.typename} in this type store, "
                    f"{self.store.distro}); the definitions differ"
                )
        if len(self._publications) > 10_000:
            self._publications.clear()  # bounded memory; verdicts are cheap to recompute
        self._publications[handle] = refused
        return refused

    def _other_type(self, topic: RosTopic, type_name: str) -> tuple[str, str]:
        """Why a publisher of ``type_name`` on ``topic`` is refused: unknown_type or
        type_conflict."""
        ros_name = ros_type_name(type_name)
        if ros_name is None or ros_name not in self.store:
            return "unknown_type", (
                f"a publisher of the unknown type {type_name[:80]!r} (declared type: "
                f"{topic.typename})"
            )
        return "type_conflict", (
            f"a publisher of {ros_name} (declared type: {topic.typename})"
        )

    def _take_publications(self) -> None:
        """Count publishers of another type on our topics (DDS never matches them)."""
        reader = self._discovery
        if reader is None:
            return
        while endpoints := reader.take(_TAKE_BATCH):
            self._check_publications(endpoints)

    def _check_publications(self, endpoints: list[Any]) -> None:
        for endpoint in endpoints:
            if not getattr(endpoint.sample_info, "valid_data", True):
                continue
            name = endpoint.topic_name
            if not name.startswith("rt/"):
                continue
            if sum(map(len, self._seen.values())) < _MAX_SEEN:  # bounded memory
                self._seen.setdefault(name, {})[endpoint.key] = endpoint.type_name
            topic = self._topics.get(name[2:])
            if topic is not None and name[2:] in self._reading:
                self._judge(topic, endpoint.key, endpoint.type_name)

    def _judge_seen(self, name: str) -> None:
        """Judge the publishers discovery saw on ``name`` before its reader existed."""
        topic = self._topics.get(name)
        if topic is not None:
            for key, type_name in self._seen.get(dds_topic_name(name), {}).items():
                self._judge(topic, key, type_name)

    def _judge(self, topic: RosTopic, key: Any, type_name: str) -> None:
        """Count a publisher of ``topic`` with another type, once."""
        if type_name == topic.codec.dds_name or key in self._foreign:
            return
        self._foreign.add(key)
        self._reject(topic.name, *self._other_type(topic, type_name))
