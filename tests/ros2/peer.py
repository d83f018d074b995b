"""A ROS 2 peer written only with eclipse-zenoh, cyclonedds and rosbags (never rasm), run as a
subprocess by the tests: it stands for a ROS 2 node on the other side of the wire.

Usage: ``python peer.py CONFIG_JSON``. It prints JSON lines on stdout:
``{"event": "ready"}`` once its entities exist, ``{"event": "message", ...}`` per message
received, ``{"event": "published", "n": N}`` after each round of publishing, and
``{"event": "token", "key": ...}`` per liveliness token seen (Zenoh graph), ``{"event":
"graph", "gid", "nodes"}`` per ros_discovery_info sample and ``{"event": "endpoint", "kind",
"topic", "key", "participant"}`` per endpoint discovered (DDS graph). It stops when stdin
closes.

CONFIG keys: ``middleware`` (zenoh | dds), ``role`` (pub | sub | graph: the liveliness tokens
over Zenoh, ``ros_discovery_info`` and the endpoints discovered over DDS | churn: over DDS,
``rounds`` times a participant comes with a reader and a writer per topic, publishes the
messages once its writers match, leaves and says ``{"event": "round", "n": N}``),
``listen`` (Zenoh endpoint), ``connect`` (Zenoh endpoints to connect to as well), ``rmw``
(true: scouting and timestamping as rmw_zenoh's default node session sets them),
``domain``, ``repeat`` (publish again and again until stdin closes), ``msg`` (``[[file,
package], ...]`` custom .msg files) and ``topics``: a list of ``{"topic", "type",
"messages"}`` (dicts to publish; ``strings``: sizes of ``{"data": "xxx..."}`` messages to
add), where ``raw`` (hex payloads sent as they are), ``junk`` (sizes of payloads of 0xff
bytes), ``key`` (a Zenoh key expression), ``type_name`` (a DDS type name) and
``type_hash`` (announced in DDS user data) override what the peer would send, and
``stamp`` (true) sets the messages' ``header.stamp`` to the time each round is sent;
``"wait": false`` publishes without waiting for a DDS reader to match (one of another type
never does); ``"latched": true`` makes a DDS reader or writer transient local; ``"shm":
false`` turns Zenoh's shared memory off. ``node`` (``/name`` or ``/ns/name``) makes a
publishing peer a ROS node as rmw_zenoh and rmw_cyclonedds make one: over Zenoh its node and
publisher liveliness tokens, and each message's GID the XXH3-128 of its publisher's token;
over DDS its node and writers announced on ``ros_discovery_info``. ``gid`` (hex) sends that
GID instead, as a forger would.
"""

from __future__ import annotations

import json
import struct
import sys
import threading
import time
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

STORE = get_typestore(Stores.ROS2_JAZZY)
PRIMITIVE_DTYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "uint8": np.uint8, "int8": np.int8,
    "uint16": np.uint16, "int16": np.int16, "uint32": np.uint32, "int32": np.int32,
    "uint64": np.uint64, "int64": np.int64, "float32": np.float32, "float64": np.float64,
}


# what rmw_zenoh's DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5 sets besides mode, connect (the
# router) and listen (tcp/localhost:0): written out here, never taken from rasm
RMW_SESSION = {
    "scouting/gossip/enabled": True,
    "scouting/gossip/multihop": False,
    "scouting/gossip/target": {"router": ["router", "peer"], "peer": ["router"]},
    "scouting/gossip/autoconnect": {"router": [], "peer": ["router", "peer"]},
    "scouting/gossip/autoconnect_strategy": {
        "peer": {"to_router": "always", "to_peer": "greater-zid"},
    },
    "timestamping/enabled": True,
}


def say(**event):
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def stdin_closed() -> threading.Event:
    done = threading.Event()

    def watch():
        sys.stdin.read()
        done.set()

    threading.Thread(target=watch, daemon=True).start()
    return done


# -- rosbags objects <-> JSON-able dicts (this peer's own, independent of rasm) ----------------
def to_object(typename, value):
    fields = STORE.fielddefs[typename][1]
    kwargs = {}
    for name, desc in fields:
        kwargs[name] = field_value(desc, (value or {}).get(name))
    return STORE.types[typename](**kwargs)


def field_value(desc, value):
    kind, rest = desc
    if kind == Nodetype.NAME:
        return to_object(rest, value)
    if kind == Nodetype.BASE:
        base = rest[0]
        if value is None:
            return "" if base == "string" else (False if base == "bool" else 0)
        return value
    (inner_kind, inner), length = rest
    if value is None:
        value = [] if kind == Nodetype.SEQUENCE else [None] * length
    if inner_kind == Nodetype.NAME:
        return [to_object(inner, v) for v in value]
    if inner[0] == "string":
        return [v or "" for v in value]
    return np.array([0 if v is None else v for v in value], dtype=PRIMITIVE_DTYPES[inner[0]])


def to_plain(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, list):
        return [to_plain(v) for v in obj]
    if hasattr(obj, "__msgtype__"):
        return {
            name: to_plain(getattr(obj, name))
            for name, _ in STORE.fielddefs[obj.__msgtype__][1]
            if name != "structure_needs_at_least_one_member"
        }
    return obj


def dds_name(typename):
    package, _, name = typename.split("/")
    return f"{package}::msg::dds_::{name}_"


# -- Zenoh --------------------------------------------------------------------------------------
def zenoh_key(config, entry):
    if entry.get("key"):
        return entry["key"]
    typename = entry["type"]
    return (f"{config.get('domain', 0)}/{entry['topic'].strip('/')}/{dds_name(typename)}/"
            f"{STORE.hash_rihs01(typename)}")


def payloads_of(entry):
    if "raw" in entry:
        return [bytes.fromhex(h) for h in entry["raw"]]
    if "junk" in entry:  # that many bytes, no valid CDR of any message
        return [b"\xff" * size for size in entry["junk"]]
    messages = entry.get("messages", []) + [{"data": "x" * n} for n in entry.get("strings", [])]
    return [bytes(STORE.serialize_cdr(to_object(entry["type"], m), entry["type"]))
            for m in messages]


def this_round(entry, payloads):
    """The payloads to send now: with ``"stamp": true`` the messages' header.stamp is now."""
    if not entry.get("stamp"):
        return payloads
    now = time.time_ns()
    stamp = {"sec": now // 10**9, "nanosec": now % 10**9}
    messages = [{**m, "header": {**m.get("header", {}), "stamp": stamp}} for m in entry["messages"]]
    return payloads_of({**entry, "messages": messages})


def zenoh_main(config):
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([config["listen"]]))
    if config.get("connect"):
        conf.insert_json5("connect/endpoints", json.dumps(config["connect"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if config.get("rmw"):  # rmw_zenoh's default node session (DEFAULT_RMW_ZENOH_SESSION_CONFIG)
        for key, value in RMW_SESSION.items():
            conf.insert_json5(key, json.dumps(value))
    if config.get("shm") is False:  # big messages then go in fragments, even on one machine
        conf.insert_json5("transport/shared_memory/enabled", "false")
    session = zenoh.open(conf)
    say(event="listening")
    done = stdin_closed()
    role = config["role"]
    entities = []
    if role == "sub":
        for entry in config["topics"]:
            def on_sample(sample, entry=entry):
                attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
                data = bytes(sample.payload.to_bytes())
                say(event="message", topic=entry["topic"], key=str(sample.key_expr),
                    attachment=attachment.hex(),
                    data=to_plain(STORE.deserialize_cdr(data, entry["type"])))

            entities.append(session.declare_subscriber(zenoh_key(config, entry), on_sample))
        say(event="ready")
        done.wait()
    elif role == "server":
        entities.extend(server_main(config, session, done))
    elif role == "graph":
        entities.append(session.liveliness().declare_subscriber(
            "@ros2_lv/**", lambda s: say(event="token", key=str(s.key_expr), kind=str(s.kind)),
            history=True,
        ))
        say(event="ready")
        done.wait()
    else:
        publishers = [
            (session.declare_publisher(zenoh_key(config, entry),
                                       congestion_control=zenoh.CongestionControl.BLOCK),
             entry, payloads_of(entry))
            for entry in config["topics"]
        ]
        gids = {}
        if config.get("node"):
            entities.extend(zenoh_node(session, config, gids))
        for publisher, _, _ in publishers:
            while not publisher.matching_status.matching and not done.is_set():
                done.wait(0.01)  # poll the match: zenoh-python offers no blocking wait for it
        say(event="ready")
        sequence = 0
        numbers = iter(config.get("sequences", ()))  # the sequence numbers to send, if given
        gid = bytes(range(16))
        if config.get("gid"):
            gid = bytes.fromhex(config["gid"])
        while True:
            for publisher, entry, payloads in publishers:
                for payload in this_round(entry, payloads):
                    sequence = next(numbers, sequence + 1)
                    sender = gids.get(entry["topic"], gid)
                    attachment = struct.pack("<qqB16s", sequence, time.time_ns(), 16, sender)
                    publisher.put(payload, attachment=attachment)
            say(event="published", n=sequence)
            if not config.get("repeat") or done.wait(0.05):
                break
        done.wait()
        entities += [p for p, _, _ in publishers]
    for entity in entities:
        entity.undeclare()
    session.close()


def zenoh_node(session, config, gids):
    """rmw_zenoh's liveliness tokens of a node and its publishers; fills ``gids`` (topic ->
    the GID rmw_zenoh derives from the publisher's token)."""
    import xxhash

    namespace, _, name = config["node"].rpartition("/")
    head = f"@ros2_lv/{config.get('domain', 0)}/{session.zid()}/0"
    where = f"%/{(namespace or '/').replace('/', '%')}/{name}"
    tokens = [session.liveliness().declare_token(f"{head}/0/NN/{where}")]
    for i, entry in enumerate(config["topics"], start=1):
        typename = entry["type"]
        key = (f"{head}/{i}/MP/{where}/{entry['topic'].replace('/', '%')}/{dds_name(typename)}/"
               f"{STORE.hash_rihs01(typename)}/::,10:,:,:,,")
        digest = xxhash.xxh3_128_intdigest(key.encode())
        gids[entry["topic"]] = (digest & (2**64 - 1)).to_bytes(8, "little") + \
            (digest >> 64).to_bytes(8, "little")
        tokens.append(session.liveliness().declare_token(key))
    return tokens


# -- Cyclone DDS --------------------------------------------------------------------------------
def dds_main(config):
    from cyclonedds._clayer import ddspy_take, ddspy_write
    from cyclonedds.core import InstanceState, SampleState, ViewState
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as t
    from cyclonedds.pub import DataWriter
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    primitives = {
        "bool": bool, "byte": t.byte, "char": t.uint8, "uint8": t.uint8, "int8": t.int8,
        "int16": t.int16, "uint16": t.uint16, "int32": t.int32, "uint32": t.uint32,
        "int64": t.int64, "uint64": t.uint64, "float32": t.float32, "float64": t.float64,
    }
    made = {}

    def idl(desc):
        kind, rest = desc
        if kind == Nodetype.NAME:
            return struct_of(rest)
        if kind == Nodetype.BASE:
            if rest[0] == "string":
                return t.bounded_str[rest[1]] if rest[1] else str
            return primitives[rest[0]]
        inner, length = rest
        if kind == Nodetype.ARRAY:
            return t.array[idl(inner), length]
        return t.sequence[idl(inner), length] if length else t.sequence[idl(inner)]

    def struct_of(typename, name=None):
        key = (typename, name)
        if key not in made:
            fields = {f: idl(d) for f, d in STORE.fielddefs[typename][1]}
            made[key] = make_idl_struct(
                typename.replace("/", "_") + "_peer" + str(len(made)), name or dds_name(typename),
                fields,
            )
        return made[key]

    done = stdin_closed()
    mask = SampleState.Any | ViewState.Any | InstanceState.Any

    def qos_of(entry):
        return Qos(
            Policy.Reliability.Reliable(10**8), Policy.History.KeepLast(100),
            Policy.Durability.TransientLocal if entry.get("latched")
            else Policy.Durability.Volatile,
            Policy.DataRepresentation(use_cdrv0_representation=True),
            *([Policy.Userdata(f"typehash={entry['type_hash']};".encode())]
              if entry.get("type_hash") else []),
        )

    if config["role"] == "churn":
        # participants that come, match, publish and leave, round after round
        for n in range(config["rounds"]):
            participant = DomainParticipant(config.get("domain", 0))
            writers = []
            for entry in config["topics"]:
                qos = qos_of(entry)
                topic = Topic(participant, "rt" + entry["topic"], struct_of(entry["type"]),
                              qos=qos)
                DataReader(participant, topic, qos=qos)  # a reader too: rasm's writer matches it
                writers.append((DataWriter(participant, topic, qos=qos), entry))
            for writer, _ in writers:
                while not writer.get_matched_subscriptions() and not done.is_set():
                    done.wait(0.002)
            for writer, entry in writers:
                for payload in payloads_of(entry):
                    ddspy_write(writer._ref, payload + b"\0" * (-len(payload) % 4))
            participant.__del__()  # leaves now, its readers and writers with it
            say(event="round", n=n + 1)
            if done.is_set():
                return
        done.wait()
        return
    participant = DomainParticipant(config.get("domain", 0))
    if config["role"] == "graph":
        dds_graph(participant, struct_of, done)
        return
    if config["role"] == "server":
        dds_server(config, participant, idl, done)
        return
    endpoints = []
    for entry in config["topics"]:
        qos = qos_of(entry)
        topic = Topic(participant, "rt" + entry["topic"],
                      struct_of(entry["type"], entry.get("type_name")), qos=qos)
        if config["role"] == "sub":
            endpoints.append((entry, DataReader(participant, topic, qos=qos)))
        else:
            endpoints.append((entry, DataWriter(participant, topic, qos=qos)))
    if config["role"] == "sub":
        say(event="ready")
        while not done.is_set():
            idle = True
            for entry, reader in endpoints:
                samples = ddspy_take(reader._ref, mask, 64)
                for data, info in samples if not isinstance(samples, int) else []:
                    idle = False
                    if info.valid_data:
                        say(event="message", topic=entry["topic"],
                            data=to_plain(STORE.deserialize_cdr(data, entry["type"])))
            if idle:
                done.wait(0.005)  # poll: this peer has no listener thread of its own
        return
    graph = dds_node(participant, struct_of, config["node"], [w for _, w in endpoints]) \
        if config.get("node") else None
    for entry, writer in endpoints:
        while entry.get("wait", True) and not writer.get_matched_subscriptions() \
                and not done.is_set():
            done.wait(0.01)
    say(event="ready")
    written = 0
    payloads = [(writer, entry, payloads_of(entry)) for entry, writer in endpoints]
    while True:
        for writer, entry, items in payloads:
            for payload in this_round(entry, items):
                ddspy_write(writer._ref, payload + b"\0" * (-len(payload) % 4))
                written += 1
        say(event="published", n=written)
        if not config.get("repeat") or done.wait(0.05):
            break
    done.wait()
    del graph  # the node's announcement stays as long as the peer


def dds_node(participant, struct_of, node, writers):
    """rmw_cyclonedds's announcement of a node and its writers on ros_discovery_info; returns
    the writer that keeps it there (transient local) while the peer lives."""
    from cyclonedds.pub import DataWriter
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.topic import Topic

    graph_type = "rmw_dds_common/msg/ParticipantEntitiesInfo"
    qos = Qos(Policy.Reliability.Reliable(10**8), Policy.Durability.TransientLocal,
              Policy.History.KeepLast(1),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    topic = Topic(participant, "ros_discovery_info", struct_of(graph_type), qos=qos)
    writer = DataWriter(participant, topic, qos=qos)
    namespace, _, name = node.rpartition("/")

    def gid(entity):
        return {"data": list(entity.guid.bytes.ljust(16, b"\0"))}

    info = {"gid": gid(participant), "node_entities_info_seq": [{
        "node_namespace": namespace or "/", "node_name": name, "reader_gid_seq": [],
        "writer_gid_seq": [gid(w) for w in writers]}]}
    data = bytes(STORE.serialize_cdr(to_object(graph_type, info), graph_type))
    from cyclonedds._clayer import ddspy_write

    ddspy_write(writer._ref, data + b"\0" * (-len(data) % 4))
    return writer


def dds_graph(participant, struct_of, done):
    """What `ros2 node list` reads over DDS: the ParticipantEntitiesInfo samples on
    ros_discovery_info, and the endpoints DDS discovery announces (their GUIDs)."""
    from cyclonedds.builtin import (
        BuiltinDataReader,
        BuiltinTopicDcpsPublication,
        BuiltinTopicDcpsSubscription,
    )
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    graph_type = "rmw_dds_common/msg/ParticipantEntitiesInfo"
    qos = Qos(Policy.Reliability.Reliable(10**8), Policy.Durability.TransientLocal,
              Policy.History.KeepLast(1),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    topic = Topic(participant, "ros_discovery_info", struct_of(graph_type), qos=qos)
    info = DataReader(participant, topic, qos=qos)
    builtin = [(kind, BuiltinDataReader(participant, what)) for kind, what in
               (("writer", BuiltinTopicDcpsPublication), ("reader", BuiltinTopicDcpsSubscription))]
    say(event="ready")

    def gid(g):
        return bytes(g.data).hex()

    while not done.is_set():
        for sample in info.take(64):
            say(event="graph", gid=gid(sample.gid), nodes=[
                {"namespace": n.node_namespace, "name": n.node_name,
                 "readers": [gid(g) for g in n.reader_gid_seq],
                 "writers": [gid(g) for g in n.writer_gid_seq]}
                for n in sample.node_entities_info_seq
            ])
        for kind, reader in builtin:
            for sample in reader.take(64):
                say(event="endpoint", kind=kind, topic=sample.topic_name,
                    key=sample.key.bytes.hex(), participant=sample.participant_key.bytes.hex())
        done.wait(0.01)  # poll: this peer has no listener thread of its own


def main():
    config = json.loads(sys.argv[1])
    for file, package in config.get("msg", []):
        path = Path(file)
        STORE.register(get_types_from_msg(path.read_text(), f"{package}/msg/{path.stem}"))
    (zenoh_main if config["middleware"] == "zenoh" else dds_main)(config)



# -- a service and action server (role "server") -----------------------------------------------
# Written with eclipse-zenoh and rosbags alone: test_msgs' BasicTypes service (the response
# echoes the request with int32_value doubled) and Fibonacci action (feedback after each step,
# result when done; "hang": never done unless cancelled). Keys: rmw_zenoh's, the data types
# hashed by rosbags; the service keys are matched with wildcards for type and hash.
BASIC = """bool bool_value
byte byte_value
char char_value
float32 float32_value
float64 float64_value
int8 int8_value
uint8 uint8_value
int16 int16_value
uint16 uint16_value
int32 int32_value
uint32 uint32_value
int64 int64_value
uint64 uint64_value
string string_value
"""


def _server_types():
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    name = (Nodetype.NAME, "unique_identifier_msgs/msg/UUID")
    ints = (Nodetype.SEQUENCE, ((Nodetype.BASE, ("int32", 0)), 0))
    defs = dict(get_types_from_msg(BASIC, "peer/msg/Basic"))
    defs.update({
        "peer/msg/SendGoalRequest": ([], [("goal_id", name),
                                          ("order", (Nodetype.BASE, ("int32", 0)))]),
        "peer/msg/SendGoalResponse": ([], [
            ("accepted", (Nodetype.BASE, ("bool", 0))),
            ("stamp", (Nodetype.NAME, "builtin_interfaces/msg/Time")),
        ]),
        "peer/msg/GoalIdOnly": ([], [("goal_id", name)]),
        "peer/msg/ResultResponse": ([], [("status", (Nodetype.BASE, ("int8", 0))),
                                         ("sequence", ints)]),
        "test_msgs/action/Fibonacci_Feedback": ([], [("sequence", ints)]),
        "test_msgs/action/Fibonacci_FeedbackMessage": ([], [
            ("goal_id", name), ("feedback", (Nodetype.NAME, "test_msgs/action/Fibonacci_Feedback"))
        ]),
        "peer/msg/CancelResponse": ([], [
            ("return_code", (Nodetype.BASE, ("int8", 0))),
            ("goals_canceling",
             (Nodetype.SEQUENCE, ((Nodetype.NAME, "action_msgs/msg/GoalInfo"), 0))),
        ]),
    })
    store.register(defs)
    return store


def server_main(config, session, done):
    import zenoh

    store = _server_types()
    domain = config.get("domain", 0)
    types = store.types

    def encode(typename, **fields):
        return bytes(store.serialize_cdr(types[typename](**fields), typename))

    def uuid(goal_id):
        return bytes(goal_id.uuid).hex()

    entities = []
    service = config.get("service")
    if service:
        def on_basic(query):
            request = store.deserialize_cdr(query.payload.to_bytes(), "peer/msg/Basic")
            say(event="request", key=str(query.key_expr), int32_value=int(request.int32_value))
            request.int32_value *= 2
            query.reply(query.key_expr, bytes(store.serialize_cdr(request, "peer/msg/Basic")),
                        attachment=query.attachment)

        entities.append(session.declare_queryable(f"{domain}/{service.strip('/')}/*/*",
                                                  on_basic))
    action = config.get("action")
    if action:
        base = f"{domain}/{action.strip('/')}/_action"
        fb_type = "test_msgs/action/Fibonacci_FeedbackMessage"
        feedback_pub = session.declare_publisher(
            f"{base}/feedback/test_msgs::action::dds_::Fibonacci_FeedbackMessage_/"
            f"{store.hash_rihs01(fb_type)}"
        )
        goals = {}  # goal id (hex) -> {"cancelled": Event, "results": [queries], "outcome"}
        lock = threading.Lock()

        def finish(goal, status, sequence):
            with lock:
                goal["outcome"] = (status, sequence)
                waiting, goal["results"] = goal["results"], []
            for query in waiting:
                reply_result(query, status, sequence)

        def reply_result(query, status, sequence):
            query.reply(query.key_expr, encode("peer/msg/ResultResponse", status=status,
                                               sequence=np.array(sequence, dtype=np.int32)),
                        attachment=query.attachment)
            query.drop()

        def pursue(goal_id, order, goal):
            sequence = [0, 1][:max(order, 0)]
            step = 0
            while goal["hang"] or len(sequence) < order:
                if goal["cancelled"].wait(config.get("period", 0.05)):
                    finish(goal, 5, sequence)
                    return
                if not goal["hang"]:
                    sequence.append(sequence[-1] + sequence[-2] if len(sequence) > 1 else 1)
                step += 1
                feedback_pub.put(encode(
                    fb_type, goal_id=types["unique_identifier_msgs/msg/UUID"](
                        uuid=np.frombuffer(bytes.fromhex(goal_id), dtype=np.uint8)),
                    feedback=types["test_msgs/action/Fibonacci_Feedback"](
                        sequence=np.array(sequence, dtype=np.int32)),
                ))
            finish(goal, 4, sequence)

        def on_send_goal(query):
            request = store.deserialize_cdr(query.payload.to_bytes(), "peer/msg/SendGoalRequest")
            goal_id = uuid(request.goal_id)
            say(event="goal", key=str(query.key_expr), goal=goal_id, order=int(request.order))
            accepted = request.order >= 0
            goal = {"cancelled": threading.Event(), "results": [], "outcome": None,
                    "hang": bool(config.get("hang"))}
            if accepted:
                with lock:
                    goals[goal_id] = goal
            query.reply(query.key_expr, encode(
                "peer/msg/SendGoalResponse", accepted=accepted,
                stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)),
                attachment=query.attachment)
            if accepted:
                threading.Thread(target=pursue, args=(goal_id, int(request.order), goal),
                                 daemon=True).start()

        def take_results(queryable):
            while True:
                try:
                    query = queryable.handler.recv()
                except zenoh.ZError:
                    return
                request = store.deserialize_cdr(query.payload.to_bytes(), "peer/msg/GoalIdOnly")
                with lock:
                    goal = goals.get(uuid(request.goal_id))
                    outcome = goal and goal["outcome"]
                    if goal is not None and outcome is None:
                        goal["results"].append(query)
                if goal is None:
                    reply_result(query, 0, [])
                elif outcome is not None:
                    reply_result(query, *outcome)

        def on_cancel(query):
            request = store.deserialize_cdr(query.payload.to_bytes(), "action_msgs/msg/GoalInfo")
            goal_id = uuid(request.goal_id)
            say(event="cancelled", key=str(query.key_expr), goal=goal_id)
            with lock:
                goal = goals.get(goal_id)
            if goal is not None:
                goal["cancelled"].set()
            query.reply(query.key_expr, encode(
                "peer/msg/CancelResponse", return_code=0 if goal else 2,
                goals_canceling=[request] if goal else []), attachment=query.attachment)

        results = session.declare_queryable(f"{base}/get_result/*/*",
                                            zenoh.handlers.FifoChannel(64))
        threading.Thread(target=take_results, args=(results,), daemon=True).start()
        entities += [
            session.declare_queryable(f"{base}/send_goal/*/*", on_send_goal),
            session.declare_queryable(f"{base}/cancel_goal/*/*", on_cancel),
            results, feedback_pub,
        ]
    say(event="ready")
    done.wait()
    return entities



# -- the same server over DDS (role "server", middleware "dds") ----------------------------------
# Written with cyclonedds and rosbags alone, as rmw_cyclonedds makes a service: requests on
# rq/<service>Request, replies on rr/<service>Reply, each sample starting (after its CDR header)
# with the request id rmw_cyclonedds puts there (cdds_request_header_t: the client's 64-bit
# guid, the request's int64 sequence number), which the reply repeats. The types come from
# test_msgs' own .srv and .action files (config "interfaces": their folder).
def _dds_server_types(folder):
    name = lambda target: (Nodetype.NAME, target)  # noqa: E731
    uuid = ("goal_id", name("unique_identifier_msgs/msg/UUID"))
    srv = (Path(folder) / "srv" / "BasicTypes.srv").read_text().split("---")
    goal, result, feedback = (Path(folder) / "action" / "Fibonacci.action").read_text().split(
        "---")
    defs = {}
    for text, typename in ((srv[0], "test_msgs/srv/BasicTypes_Request"),
                           (srv[1], "test_msgs/srv/BasicTypes_Response"),
                           (goal, "test_msgs/action/Fibonacci_Goal"),
                           (result, "test_msgs/action/Fibonacci_Result"),
                           (feedback, "test_msgs/action/Fibonacci_Feedback")):
        # (rosbags would name a pkg/srv/Name_Request pkg/srv/msg/Name_Request: keep the name)
        defs[typename] = next(iter(get_types_from_msg(text, typename).values()))
    fib = "test_msgs/action/Fibonacci"
    defs.update({
        f"{fib}_SendGoal_Request": ([], [uuid, ("goal", name(f"{fib}_Goal"))]),
        f"{fib}_SendGoal_Response": ([], [("accepted", (Nodetype.BASE, ("bool", 0))),
                                          ("stamp", name("builtin_interfaces/msg/Time"))]),
        f"{fib}_GetResult_Request": ([], [uuid]),
        f"{fib}_GetResult_Response": ([], [("status", (Nodetype.BASE, ("int8", 0))),
                                           ("result", name(f"{fib}_Result"))]),
        f"{fib}_FeedbackMessage": ([], [uuid, ("feedback", name(f"{fib}_Feedback"))]),
        "action_msgs/srv/CancelGoal_Request": ([], [("goal_info",
                                                     name("action_msgs/msg/GoalInfo"))]),
        "action_msgs/srv/CancelGoal_Response": ([], [
            ("return_code", (Nodetype.BASE, ("int8", 0))),
            ("goals_canceling", (Nodetype.SEQUENCE, (name("action_msgs/msg/GoalInfo"), 0)))]),
    })
    STORE.register(defs)


def dds_server(config, participant, idl, done):
    from cyclonedds._clayer import ddspy_take, ddspy_write
    from cyclonedds.core import InstanceState, SampleState, ViewState
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as t
    from cyclonedds.pub import DataWriter
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    _dds_server_types(config["interfaces"])
    types = STORE.types
    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    qos = Qos(Policy.Reliability.Reliable(10**8), Policy.History.KeepLast(100),
              Policy.Durability.Volatile,
              Policy.DataRepresentation(use_cdrv0_representation=True))

    def wrapped(typename):
        """The DDS struct of a request or reply: the request id, then the message's fields."""
        fields = {"request_guid": t.uint64, "request_seq": t.int64}
        fields.update({f: idl(d) for f, d in STORE.fielddefs[typename][1]})
        return make_idl_struct(typename.replace("/", "_") + "_wire", dds_name(typename), fields)

    def encode(typename, message):
        return bytes(STORE.serialize_cdr(message, typename))

    services = []  # (reader, writer, request type, response type, handler)

    def serve(service, typename, handler):
        reader = DataReader(participant, Topic(participant, f"rq{service}Request",
                                               wrapped(f"{typename}_Request")), qos=qos)
        writer = DataWriter(participant, Topic(participant, f"rr{service}Reply",
                                               wrapped(f"{typename}_Response")), qos=qos)
        services.append((reader, writer, typename, handler))

    def reply(writer, typename, request_id, message):
        data = encode(f"{typename}_Response", message)
        wire = data[:4] + request_id + data[4:]
        for _ in range(100):  # the client's reply reader is matched before it is answered
            if writer.get_matched_subscriptions():
                break
            done.wait(0.01)
        ddspy_write(writer._ref, wire + b"\0" * (-len(wire) % 4))

    lock = threading.Lock()
    goals = {}  # goal id (hex) -> {"cancelled": Event, "results": [...], "outcome": ...}
    if config.get("service"):
        def on_basic(request, respond):
            say(event="request", topic=config["service"], int32_value=int(request.int32_value))
            request.int32_value *= 2
            respond(types["test_msgs/srv/BasicTypes_Response"](**{
                f: getattr(request, f) for f, _ in
                STORE.fielddefs["test_msgs/srv/BasicTypes_Response"][1]}))

        serve(config["service"], "test_msgs/srv/BasicTypes", on_basic)
    action = config.get("action")
    if action:
        fib = "test_msgs/action/Fibonacci"
        fb_type = f"{fib}_FeedbackMessage"
        feedback_writer = DataWriter(participant, Topic(
            participant, f"rt{action}/_action/feedback",
            make_idl_struct("peer_feedback_wire", dds_name(fb_type),
                            {f: idl(d) for f, d in STORE.fielddefs[fb_type][1]})), qos=qos)

        def result_message(status, sequence):
            return types[f"{fib}_GetResult_Response"](status=status, result=types[
                f"{fib}_Result"](sequence=np.array(sequence, dtype=np.int32)))

        def finish(goal, status, sequence):
            with lock:
                goal["outcome"] = (status, sequence)
                waiting, goal["results"] = goal["results"], []
            for respond in waiting:
                respond(result_message(status, sequence))

        def pursue(goal_id, order, goal):
            sequence = [0, 1][:max(order, 0)]
            while goal["hang"] or len(sequence) < order:
                if goal["cancelled"].wait(config.get("period", 0.05)):
                    finish(goal, 5, sequence)
                    return
                if not goal["hang"]:
                    sequence.append(sequence[-1] + sequence[-2] if len(sequence) > 1 else 1)
                data = encode(fb_type, types[fb_type](
                    goal_id=types["unique_identifier_msgs/msg/UUID"](
                        uuid=np.frombuffer(bytes.fromhex(goal_id), dtype=np.uint8)),
                    feedback=types[f"{fib}_Feedback"](sequence=np.array(sequence,
                                                                         dtype=np.int32))))
                ddspy_write(feedback_writer._ref, data + b"\0" * (-len(data) % 4))
            finish(goal, 4, sequence)

        def on_send_goal(request, respond):
            goal_id = bytes(request.goal_id.uuid).hex()
            say(event="goal", topic=action, goal=goal_id, order=int(request.goal.order))
            accepted = request.goal.order >= 0
            goal = {"cancelled": threading.Event(), "results": [], "outcome": None,
                    "hang": bool(config.get("hang"))}
            if accepted:
                with lock:
                    goals[goal_id] = goal
            respond(types[f"{fib}_SendGoal_Response"](
                accepted=accepted, stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)))
            if accepted:
                threading.Thread(target=pursue, args=(goal_id, int(request.goal.order), goal),
                                 daemon=True).start()

        def on_get_result(request, respond):
            with lock:
                goal = goals.get(bytes(request.goal_id.uuid).hex())
                outcome = goal and goal["outcome"]
                if goal is not None and outcome is None:
                    goal["results"].append(respond)
            if goal is None:
                respond(result_message(0, []))
            elif outcome is not None:
                respond(result_message(*outcome))

        def on_cancel(request, respond):
            goal_id = bytes(request.goal_info.goal_id.uuid).hex()
            say(event="cancelled", topic=action, goal=goal_id)
            with lock:
                goal = goals.get(goal_id)
            if goal is not None:
                goal["cancelled"].set()
            respond(types["action_msgs/srv/CancelGoal_Response"](
                return_code=0 if goal else 2,
                goals_canceling=[request.goal_info] if goal else []))

        base = f"{action}/_action"
        serve(f"{base}/send_goal", f"{fib}_SendGoal", on_send_goal)
        serve(f"{base}/get_result", f"{fib}_GetResult", on_get_result)
        serve(f"{base}/cancel_goal", "action_msgs/srv/CancelGoal", on_cancel)
    say(event="ready")
    while not done.is_set():
        idle = True
        for reader, writer, typename, handler in services:
            samples = ddspy_take(reader._ref, mask, 64)
            for data, info in samples if not isinstance(samples, int) else []:
                if not info.valid_data:
                    continue
                idle = False
                request_id = data[4:20]
                request = STORE.deserialize_cdr(data[:4] + data[20:], f"{typename}_Request")
                handler(request, lambda message, writer=writer, typename=typename,
                        request_id=request_id: reply(writer, typename, request_id, message))
        if idle:
            done.wait(0.005)  # poll: this peer has no listener thread of its own


if __name__ == "__main__":
    main()
