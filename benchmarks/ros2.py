"""ROS 2 speed: ingest of /odom-sized messages over Zenoh and DDS, rosbag2 decoding, the
detect-to-act latency of a loop managing a ROS 2 robot over Zenoh, and `rasm check` on a bag.

Ingest: a publisher process (eclipse-zenoh or cyclonedds with rosbags, no rasm) sends N
nav_msgs/msg/Odometry messages (724 bytes of CDR) as fast as it can, on loopback. In this
process, in turn,

- a bare subscriber (eclipse-zenoh callback / cyclonedds listener) decodes each with rosbags,
- rasm's ZenohTransport / DdsTransport delivers each to a callback as a dict (keep-all QoS);
- `rasm run`'s platform (wall clock, keep-all QoS on /odom, built as `rasm run` builds it)
  takes each into knowledge and its monitors: Telegraf reads the speed field, knowledge stores
  it, the trace record is checked against the app's property and the loop's own (9 in all);

the rate is messages received per second, first to last. Each case runs 3 times, the three
cases taking turns; the median counts. Bag: a bag of N Odometry messages (MCAP) is read and
decoded by rosbags' AnyReader and by rasm's BagReader.

Latency: a robot process (eclipse-zenoh and rosbags, no rasm) publishes Odometry at 200
messages/s, with a burst of fast ones four times a second; a platform in this process (`rasm
run`'s, on the wall clock, over ZenohTransport) finds each burst in Analyse and sends a Twist,
which the robot timestamps on receipt. Detect-to-act is from the platform's ``anomaly`` record
to that receipt (one machine, one wall clock), as benchmarks/latency_loop.py measures it over
MQTT.

Check: ``rasm check`` (the property file of the latency app, the app's probes) on an MCAP bag
of N Odometry messages, against rosbags' own decode of the same bag (AnyReader +
deserialize), both in messages/s.

Run: ``.venv/bin/python benchmarks/ros2.py [--count N] [--seconds S]``. The ratios print
last. Figures are recorded in docs/ros2.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CYCLONE_LOOPBACK = (
    '<CycloneDDS><Domain id="any"><General><Interfaces>'
    '<NetworkInterface address="127.0.0.1"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General>"
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers>'
    "<ParticipantIndex>auto</ParticipantIndex></Discovery></Domain></CycloneDDS>"
)
os.environ.setdefault("CYCLONEDDS_URI", CYCLONE_LOOPBACK)

TYPE = "nav_msgs/msg/Odometry"
TOPIC = "/odom"
RUNS = 3
WAIT = 60.0


def odometry_cdr() -> bytes:
    from rasm.ros2 import TypeStore

    return TypeStore().codec(TYPE).encode({
        "header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "odom"},
        "child_frame_id": "base_link",
        "pose": {"pose": {"position": {"x": 1.0, "y": 2.0}, "orientation": {"w": 1.0}},
                 "covariance": [0.01] * 36},
        "twist": {"twist": {"linear": {"x": 0.2}, "angular": {"z": 0.1}},
                  "covariance": [0.01] * 36},
    })


# -- the publisher process (no rasm on the wire side) -------------------------------------------
def publish(middleware: str, where: str, count: int) -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    data = odometry_cdr()
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    if middleware == "zenoh":
        import zenoh

        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{where}"]))
        config.insert_json5("scouting/multicast/enabled", "false")
        session = zenoh.open(config)
        key = f"0/odom/nav_msgs::msg::dds_::Odometry_/{store.hash_rihs01(TYPE)}"
        publisher = session.declare_publisher(
            key, congestion_control=zenoh.CongestionControl.BLOCK)
        print("listening", flush=True)
        while not publisher.matching_status.matching:
            done.wait(0.01)
        attachment = bytes(33)
        for _ in range(count):
            publisher.put(data, attachment=attachment)
    else:
        from cyclonedds._clayer import ddspy_write
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.qos import Policy, Qos
        from cyclonedds.topic import Topic

        from rasm.ros2 import TypeStore
        from rasm.ros2.dds import idl_struct

        participant = DomainParticipant(int(where))
        qos = Qos(Policy.Reliability.Reliable(10**9), Policy.History.KeepAll,
                  Policy.DataRepresentation(use_cdrv0_representation=True))
        topic = Topic(participant, "rt/odom", idl_struct(TypeStore(), TYPE), qos=qos)
        writer = DataWriter(participant, topic, qos=qos)
        print("listening", flush=True)
        while not writer.get_matched_subscriptions():
            done.wait(0.01)
        padded = data + b"\0" * (-len(data) % 4)
        for _ in range(count):
            ddspy_write(writer._ref, padded)
    print("published", flush=True)
    done.wait()


class Receiver:
    """Counts arrivals; notes the first and last time."""

    def __init__(self, count: int) -> None:
        self.count = count
        self.n = 0
        self.first = self.last = 0.0
        self.done = threading.Event()

    def hit(self, *_: object) -> None:
        now = time.perf_counter()
        if self.n == 0:
            self.first = now
        self.n += 1
        self.last = now
        if self.n >= self.count:
            self.done.set()

    def rate(self) -> float:
        return (self.n - 1) / (self.last - self.first) if self.n > 1 else 0.0


def run_case(middleware: str, kind: str, count: int) -> tuple[float, int]:
    from rasm.testing.servers import free_port

    where = str(free_port()) if middleware == "zenoh" else str(100 + os.getpid() % 100)
    publisher = subprocess.Popen(
        [sys.executable, __file__, "publish", middleware, where, str(count)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )
    assert publisher.stdout is not None
    publisher.stdout.readline()  # "listening"
    receiver = Receiver(count)
    cleanup = []
    try:
        start = {"bare": start_bare, "transport": start_rasm, "platform": start_platform}[kind]
        cleanup.append(start(middleware, where, receiver))
        receiver.done.wait(WAIT)
        time.sleep(0.2)  # let stragglers in before closing: they count in n, not in the rate
    finally:
        for close in cleanup:
            close()
        publisher.stdin.close()  # type: ignore[union-attr]
        try:
            publisher.wait(10)
        except subprocess.TimeoutExpired:  # stuck sending to a receiver that failed
            publisher.kill()
            publisher.wait()
    return receiver.rate(), receiver.n


def start_rasm(middleware: str, where: str, receiver: Receiver):
    from rasm.ros2 import DdsTransport, ZenohTransport

    options = {"types": {TOPIC: TYPE}, "qos": {TOPIC: {"history": "keep_all"}},
               "max_pending": 1_000_000}
    if middleware == "zenoh":
        transport = ZenohTransport(f"zenoh://127.0.0.1:{where}", **options)
    else:
        transport = DdsTransport(f"dds://?domain={where}", **options)
    transport.subscribe(TOPIC, receiver.hit)
    transport.connect()
    return transport.close


def start_platform(middleware: str, where: str, receiver: Receiver):
    """`rasm run`'s platform on the wall clock: each Odometry read by Telegraf, stored in
    knowledge, traced and checked by the app's monitor; a record with its speed is a hit.
    Built as `rasm run` builds it on the wall clock (``low_latency``: what was built before
    the run is out of the garbage collector's reach)."""
    from rasm import Platform, RunOptions

    tmp = tempfile.TemporaryDirectory()
    app = write_latency_app(Path(tmp.name) / "ingest", qos="{history: keep_all}")
    url = f"zenoh://127.0.0.1:{where}" if middleware == "zenoh" else f"dds://?domain={where}"
    platform = Platform(app, RunOptions(
        transport=url,
        clock="wall",
        state_dir=Path(tmp.name) / "state",
        low_latency=True,
    ))
    platform.on_record.append(lambda _t, record: "speed" in record and receiver.hit())
    runner = threading.Thread(target=platform.run, args=(WAIT + 10,), daemon=True)
    runner.start()

    def close() -> None:
        platform.request_stop("the benchmark is done")
        runner.join(30)
        tmp.cleanup()

    return close


def start_bare(middleware: str, where: str, receiver: Receiver):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    if middleware == "zenoh":
        import zenoh

        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{where}"]))
        config.insert_json5("scouting/multicast/enabled", "false")
        session = zenoh.open(config)
        key = f"0/odom/nav_msgs::msg::dds_::Odometry_/{store.hash_rihs01(TYPE)}"

        def on_sample(sample):
            receiver.hit(store.deserialize_cdr(sample.payload.to_bytes(), TYPE))

        session.declare_subscriber(key, on_sample)
        return session.close
    from cyclonedds._clayer import ddspy_take
    from cyclonedds.core import InstanceState, Listener, SampleState, ViewState
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from rasm.ros2 import TypeStore
    from rasm.ros2.dds import idl_struct

    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    participant = DomainParticipant(int(where))
    qos = Qos(Policy.Reliability.Reliable(10**9), Policy.History.KeepAll,
              Policy.DataRepresentation(use_cdrv0_representation=True))
    topic = Topic(participant, "rt/odom", idl_struct(TypeStore(), TYPE), qos=qos)
    readers = []

    def on_data(_):
        while samples := ddspy_take(readers[0]._ref, mask, 64):
            for data, _info in samples:
                receiver.hit(store.deserialize_cdr(data, TYPE))

    readers.append(DataReader(participant, topic, qos=qos,
                              listener=Listener(on_data_available=on_data)))
    return lambda: participant.__del__()


def rosbags_decode_rate(bag: Path) -> float:
    """Messages per second rosbags' AnyReader reads and deserializes from ``bag``."""
    from rosbags.highlevel import AnyReader

    start = time.perf_counter()
    with AnyReader([bag]) as reader:
        n = sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype))
    return n / (time.perf_counter() - start)


def bag_rates(count: int) -> tuple[float, float]:
    from rosbags.rosbag2 import StoragePlugin, Writer

    from rasm.ros2 import BagReader, TypeStore

    store = TypeStore()
    data = odometry_cdr()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            connection = writer.add_connection(TOPIC, TYPE, typestore=store.rosbags)
            for i in range(count):
                writer.write(connection, i * 1000, data)
        theirs, ours = [], []
        for _ in range(RUNS):
            theirs.append(rosbags_decode_rate(bag))
            start = time.perf_counter()
            n = sum(1 for _ in BagReader(bag))
            ours.append(n / (time.perf_counter() - start))
    return statistics.median(theirs), statistics.median(ours)


# -- detect-to-act latency over Zenoh ---------------------------------------------------------
LATENCY_RATE = 200.0  # Odometry messages/s the robot publishes
BURSTS_PER_S = 4.0  # fast stretches per second, each a few messages long

APP_YAML = """\
name: latency
components:
  monitor: components:Quiet
  analyse: components:Bursts
  plan:
    component: components:Stop
    produces: {speed: float, turn: float}
  execute: components:Drive
probes:
  - topic: /odom
    type: nav_msgs/msg/Odometry
    qos: QOS
    signals:
      speed: {field: twist.twist.linear.x, type: float}
effectors:
  drive:
    topic: /cmd_vel
    type: geometry_msgs/msg/Twist
    fields: {linear.x: speed, angular.z: turn}
properties: [speed.rv]
knowledge: memory
timing: off
loop:
  period: 0.01
"""
PROPS = "input speed: float\n\nproperty speed_limit:\n    always (speed <= 1.0)\n"
COMPONENTS = """\
from rasm import Action, Anomaly, Plan


class Quiet:
    def monitor(self, ctx):
        return None


class Bursts:
    # one anomaly per burst of fast odometry; its number rides in the Twist's angular.z
    def __init__(self):
        self.n = 0
        self.armed = True

    def analyse(self, ctx):
        fast = (ctx.knowledge.read_knowledge("speed") or 0.0) > 0.5
        if not fast:
            self.armed = True
            return None
        if not self.armed:
            return None
        self.armed = False
        self.n += 1
        return Anomaly(f"burst {self.n}", {"n": self.n})


class Stop:
    def plan(self, ctx):
        return Plan({"speed": 0.0, "turn": float(ctx.anomaly.data["n"])})


class Drive:
    def execute(self, ctx):
        return Action("drive", {"speed": ctx.plan["speed"], "turn": ctx.plan["turn"]})
"""


def write_latency_app(folder: Path, qos: str = "{depth: 50}") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "app.yaml").write_text(APP_YAML.replace("QOS", qos))
    (folder / "components.py").write_text(COMPONENTS)
    (folder / "speed.rv").write_text(PROPS)
    return folder


def robot(port: str, seconds: float) -> None:
    """The robot process: Odometry at LATENCY_RATE with bursts; prints each Twist's receipt."""
    import struct

    import zenoh
    from rosbags.typesys import Stores, get_typestore

    from rasm.ros2 import TypeStore

    store = get_typestore(Stores.ROS2_JAZZY)
    codec = TypeStore().codec(TYPE)
    slow, fast = (codec.encode({"twist": {"twist": {"linear": {"x": v}}}}) for v in (0.2, 0.8))
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)
    twist = "geometry_msgs/msg/Twist"

    def on_twist(sample) -> None:
        received = time.time()
        message = store.deserialize_cdr(sample.payload.to_bytes(), twist)
        print(json.dumps({"n": message.angular.z, "t": received}), flush=True)

    session.declare_subscriber(
        f"0/cmd_vel/geometry_msgs::msg::dds_::Twist_/{store.hash_rihs01(twist)}", on_twist)
    publisher = session.declare_publisher(
        f"0/odom/nav_msgs::msg::dds_::Odometry_/{store.hash_rihs01(TYPE)}")
    print("listening", flush=True)
    while not publisher.matching_status.matching:
        time.sleep(0.01)
    period, burst = 1.0 / LATENCY_RATE, int(LATENCY_RATE / BURSTS_PER_S)
    start = time.monotonic()
    for i in range(int(seconds * LATENCY_RATE)):
        data = fast if i % burst < 4 else slow
        publisher.put(data, attachment=struct.pack("<qqB16s", i + 1, time.time_ns(), 16,
                                                   bytes(16)))
        time.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
    time.sleep(0.5)  # the last Twists
    session.close()


def latency(seconds: float) -> list[float]:
    """Detect-to-act latencies (ms) of a loop managing the robot process over Zenoh."""
    import re

    from rasm import Platform, RunOptions
    from rasm.testing.servers import free_port

    port = str(free_port())
    process = subprocess.Popen(
        [sys.executable, __file__, "robot", port, str(seconds)],
        stdout=subprocess.PIPE, text=True,
    )
    assert process.stdout is not None
    process.stdout.readline()  # "listening"
    detected: dict[int, float] = {}

    def on_record(_time: float, record: dict) -> None:
        if record.get("anomaly"):
            detected[int(re.findall(r"\d+", record["explanation"])[0])] = time.time()

    with tempfile.TemporaryDirectory() as tmp:
        app = write_latency_app(Path(tmp) / "latency")
        platform = Platform(app, RunOptions(
            transport=f"zenoh://127.0.0.1:{port}",
            clock="wall",
            state_dir=Path(tmp) / "state",
            low_latency=True,
        ))
        platform.on_record.append(on_record)
        platform.run(seconds + 1.0)
    out, _ = process.communicate(timeout=30)
    acted = {int(item["n"]): item["t"] for item in map(json.loads, out.splitlines())}
    return [(acted[n] - t) * 1000 for n, t in detected.items() if n in acted]


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[max(0, min(len(ordered) - 1, -(-len(ordered) * q // 100) - 1))]


# -- rasm check on a bag ------------------------------------------------------------------------
def check_rates(count: int) -> tuple[float, float]:
    """(rosbags decode, rasm check) messages/s on one MCAP bag of ``count`` Odometry."""
    import contextlib
    import io

    from rosbags.rosbag2 import StoragePlugin, Writer

    from rasm.cli import main as rasm_main
    from rasm.ros2 import TypeStore

    codec = TypeStore().codec(TYPE)
    with tempfile.TemporaryDirectory() as tmp:
        app = write_latency_app(Path(tmp) / "latency")
        bag = Path(tmp) / "bag"
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            connection = writer.add_connection(TOPIC, TYPE, typestore=TypeStore().rosbags)
            for i in range(count):
                speed = 0.8 if i % 50 < 4 else 0.2
                data = codec.encode({"header": {"stamp": {"sec": i // 1000}},
                                     "pose": {"covariance": [0.01] * 36},
                                     "twist": {"twist": {"linear": {"x": speed}}}})
                writer.write(connection, 1_700_000_000_000_000_000 + i * 5_000_000, data)
        theirs, ours = [], []
        for _ in range(RUNS):
            theirs.append(rosbags_decode_rate(bag))
            start = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):
                code = rasm_main(["check", str(app / "speed.rv"), str(bag), "--app", str(app),
                                  "--format", "json"])
            assert code == 0
            ours.append(count / (time.perf_counter() - start))
    return statistics.median(theirs), statistics.median(ours)


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["publish"]:
        publish(args[1], args[2], int(args[3]))
        return 0
    if args[:1] == ["robot"]:
        robot(args[1], float(args[2]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=20_000, help="messages per run")
    parser.add_argument("--seconds", type=float, default=30.0, help="latency run length")
    parser.add_argument("--only", choices=["ingest", "latency", "check"], default=None)
    parser.add_argument("--middleware", choices=["zenoh", "dds"], action="append", default=None,
                        help="ingest over this middleware only (repeatable; default both)")
    options = parser.parse_args(args)
    if options.only in (None, "latency"):
        delays = latency(options.seconds)
        print(f"\nDetect-to-act over Zenoh at {LATENCY_RATE:.0f} records/s, ms "
              f"({len(delays)} adaptations)")
        for q in (50, 90, 99):
            print(f"p{q:<27} {percentile(delays, q):>10.2f}")
        print(f"latency_p99_ms     {percentile(delays, 99):.2f}   (goal < 5)")
    if options.only in (None, "check"):
        decode, check = check_rates(options.count)
        print(f"\nrasm check on a bag ({options.count} {TYPE}, MCAP), messages/s")
        print(f"{'rosbags AnyReader':<28} {decode:>10,.0f}")
        print(f"{'rasm check --app':<28} {check:>10,.0f}")
        print(f"check_ratio        {check / decode:.2f}   (goal >= 0.70)")
    if options.only not in (None, "ingest"):
        return 0
    rows = {}
    cases = {"bare": "bare + rosbags", "transport": "rasm transport",
             "platform": "rasm platform"}
    middlewares = options.middleware or ["zenoh", "dds"]
    for middleware in middlewares:
        # the cases take turns, so that a change in the machine's other load over the minute
        # weighs on all three alike and the ratios stay comparable
        results: dict[str, list[tuple[float, int]]] = {kind: [] for kind in cases}
        for _ in range(RUNS):
            for kind in cases:
                results[kind].append(run_case(middleware, kind, options.count))
        for kind, label in cases.items():
            name = f"{middleware} {label}"
            rows[name] = statistics.median(r for r, _ in results[kind])
            fewest = min(n for _, n in results[kind])
            print(f"  {name}: {rows[name]:,.0f} msg/s (fewest received: "
                  f"{fewest} of {options.count})", file=sys.stderr)
    theirs, ours = bag_rates(options.count)
    print(f"\nIngest of {TYPE} over loopback, messages/s (median of {RUNS} runs)")
    for name, rate in rows.items():
        print(f"{name:<28} {rate:>10,.0f}")
    print(f"\nBag decoding ({options.count} {TYPE}, MCAP), messages/s")
    print(f"{'rosbags AnyReader':<28} {theirs:>10,.0f}")
    print(f"{'rasm BagReader':<28} {ours:>10,.0f}")
    print("\nRatios (rasm / bare)")
    for middleware in middlewares:
        bare = rows[f"{middleware} bare + rosbags"]
        goal = "   (goal >= 0.50)" if middleware == "zenoh" else ""
        print(f"{middleware}_transport_ratio {rows[f'{middleware} rasm transport'] / bare:.2f}")
        print(f"{middleware}_ingest_ratio    {rows[f'{middleware} rasm platform'] / bare:.2f}"
              f"{goal}")
    print(f"bag_decode_ratio   {ours / theirs:.2f}   (goal >= 0.70)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
