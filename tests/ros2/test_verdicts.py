"""Verdicts out and in: rasm's verdicts on ROS 2 and MQTT topics, and the verdicts of monitors
outside rasm (a Bool verdict, Copilot's Empty triggers, the public checker's {"value": …})
as veto sources that fail closed."""

from __future__ import annotations

import json
import queue
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.cli import main
from rasm.comm import open_transport
from rasm.platform import Platform
from rasm.platform.external_verdicts import ExternalVerdicts
from rasm.platform.manifest import ExternalVerdict, load_manifest
from rasm.platform.run_options import RunOptions
from rasm.testing.servers import start_mosquitto
from tests.ros2.conftest import DATA
from tests.ros2.test_replay import record
from tests.ros2.test_run import ROBOT, finish, rasm_run

GUARD = DATA / "guard"
VETOED = GUARD / "vetoed.yaml"
HOTBOX = Path(__file__).resolve().parents[2] / "examples" / "hotbox"


@given(st.lists(st.one_of(st.booleans(), st.integers(), st.none(), st.text(max_size=3))))
def test_a_bool_or_json_source_gives_its_value_and_anything_else_is_an_error(values):
    sources = ExternalVerdicts({
        "ros": ExternalVerdict("ros", "/ok", "std_msgs/msg/Bool"),
        "mqtt": ExternalVerdict("mqtt", "checker/ok"),
    })
    assert sources.missing("ros") == ("a verdict on /ok",)
    for i, value in enumerate(values):
        for name, payload in (("ros", {"data": value}), ("mqtt", {"value": value})):
            verdict = sources.receive(name, payload, float(i))
            if isinstance(value, bool):
                assert (verdict.value, verdict.error) == (value, None)
            else:  # fail closed: no verdict is a "no", said as an error
                assert verdict.value is False and "not a verdict" in verdict.error
    assert sources.missing("ros") == (() if values else ("a verdict on /ok",))


@given(
    triggers=st.lists(st.integers(0, 100), max_size=10).map(sorted),
    checks=st.lists(st.integers(0, 120), min_size=1, max_size=20).map(sorted),
)
def test_an_empty_source_vetoes_for_hold_seconds_after_each_message(triggers, checks):
    hold = 5
    sources = ExternalVerdicts({"alarm": ExternalVerdict("alarm", "/alarm", "std_msgs/msg/Empty",
                                                         hold=hold)})
    assert sources.missing("alarm") == ()  # silence is its "yes": nothing to wait for
    latest = None
    events = sorted([(t, 0) for t in triggers] + [(t, 1) for t in checks])
    for time, kind in events:
        if kind == 0:
            latest = sources.receive("alarm", {}, float(time))
            continue
        for verdict in sources.step(float(time), {}):
            latest = verdict
        vetoed = any(t <= time < t + hold for t in triggers)
        assert latest is not None and latest.value is (not vetoed), (time, triggers)


def test_a_replay_with_a_silent_verdict_source_sends_nothing(tmp_path, monkeypatch):
    # the recording has no /monitor/ok: the checker cannot vouch for any action
    monkeypatch.chdir(tmp_path)
    bag = record(tmp_path / "bag")
    trace = tmp_path / "trace.jsonl"
    assert main(["run", str(VETOED), "--replay", str(bag), "--trace", str(trace)]) == 1
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    dropped = [r for r in records if r.get("dropped")]
    assert dropped and not any(r.get("executed") for r in records)
    assert not any("recorded_action" in r for r in records)
    assert all("veto property monitor_ok not judged yet: no value for a verdict on /monitor/ok"
               in r["explanation"] for r in dropped)


@pytest.mark.slow
def test_a_false_verdict_from_a_foreign_monitor_vetoes_over_zenoh(peers, tmp_path):
    from rasm.testing.servers import free_port

    port = free_port()
    verdicts = [{"topic": "/monitor/ok", "type": "std_msgs/msg/Bool",
                 "messages": [{"data": False}]}]
    robot = peers({"middleware": "zenoh", "role": "pub", "listen": f"tcp/127.0.0.1:{port}",
                   "repeat": True, "topics": ROBOT})
    robot.wait_for(lambda p: p.events, what="the robot peer to listen")
    monitor = peers({"middleware": "zenoh", "role": "pub",
                     "listen": f"tcp/127.0.0.1:{free_port()}",
                     "connect": [f"tcp/127.0.0.1:{port}"], "repeat": True, "node": "/monitor",
                     "topics": verdicts})
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(VETOED, f"zenoh://127.0.0.1:{port}", tmp_path, "--duration", "4",
                   "--trace", str(trace))
    robot.wait_ready()
    monitor.wait_ready()
    code, output = finish(run)
    assert code == 1, output
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    dropped = [r for r in records if r.get("dropped")]
    assert dropped and not any(r.get("executed") for r in records), output
    assert any("veto property monitor_ok violated" in r["explanation"] for r in dropped)


@pytest.mark.slow
def test_verdicts_go_out_on_mqtt_under_rasm_verdict_as_the_public_checker_words_them(tmp_path):
    broker = start_mosquitto(tmp_path)
    try:
        url = f"mqtt://127.0.0.1:{broker.port}"
        listener = open_transport(url)
        got: queue.Queue = queue.Queue()
        listener.connect()
        listener.subscribe("rasm/verdict/temperature_band", lambda m: got.put(m.payload))
        platform = Platform(HOTBOX, RunOptions(
            transport=url,
            clock="wall",
            state_dir=tmp_path / "state",
            knowledge="memory",
        ))
        platform.run(1.5)
        listener.close()
    finally:
        broker.stop()
    payload = got.get(timeout=5)
    assert set(payload) == {"value", "time"} and isinstance(payload["value"], bool)
    assert platform.verdicts_published > 0


@pytest.mark.parametrize("flag, published", [(None, False), (True, True), (False, False)])
def test_publish_verdicts_says_whether_they_go_out(tmp_path, flag, published):
    manifest = load_manifest(HOTBOX)
    manifest.publish_verdicts = flag  # None: only on a network transport
    bus = []
    platform = Platform(manifest, RunOptions(clock="simulated", state_dir=tmp_path,
                                             knowledge="memory"))
    platform.build()
    platform.assembly.transport.subscribe("#", bus.append)
    platform.run(3)
    names = {m.topic for m in bus}
    assert ("rasm/verdict/temperature_band" in names) is published
    assert (platform.verdicts_published > 0) is published



_DECIDED = st.lists(  # steps, each the verdicts it decided: (property, value, in error)
    st.lists(st.tuples(st.sampled_from(["near", "far", "foreign"]),
                       st.sampled_from([True, False, None]), st.booleans()), max_size=4),
    max_size=12,
)


def _verdict_steps(steps):
    from rasm.properties.monitor import Verdict

    index = 0
    for step in steps:
        batch = []
        for name, value, error in step:
            index += 1
            batch.append(Verdict(name, index, float(index), False if error else value,
                                 "it raised" if error else None))
        yield batch


class _Steps:
    """A monitor that decides the verdicts it is given, a step's at each record."""

    def __init__(self, steps):
        self.steps = iter(list(_verdict_steps(steps)))
        self.properties = ["near", "far", "foreign"]

    def step(self, time, record):
        return next(self.steps)

    def finish(self):
        return []

    def missing(self, name):
        return ()


def _checker(steps):
    from rasm.platform.trustworthiness_checker import TrustworthinessChecker

    return TrustworthinessChecker(monitors=[_Steps(steps)], effectors={}, send=lambda *_: None,
                                  mode_of=lambda: None)


@pytest.fixture(scope="module")
def zenoh_alone():
    """A Zenoh session that is its own meeting point (no router, no peer)."""
    from rasm.ros2 import ZenohTransport
    from rasm.testing.servers import free_port

    port = free_port()
    transport = ZenohTransport(f"zenoh://127.0.0.1:{port}", listen=[f"tcp/127.0.0.1:{port}"])
    transport.connect()
    yield transport
    transport.close()


@given(steps=_DECIDED)
def test_a_ros_verdict_topic_is_sent_to_only_when_its_value_changes(zenoh_alone, steps):
    from rasm.logs import RepeatedLogs
    from rasm.platform.verdicts_out import VerdictPublisher

    publisher = VerdictPublisher(zenoh_alone, ["near", "far"], ros=True, skip={"foreign"},
                                 logs=RepeatedLogs())
    tc = _checker(steps)
    tc.batch_observers.append(publisher.publish_all)  # as the platform wires it
    before = zenoh_alone.stats.published
    changes, last = 0, {}
    for _ in steps:
        for verdict in tc.observe(0.0, {}):
            if verdict.value is None or verdict.property == "foreign":
                continue
            value = verdict.value is True and verdict.error is None
            changes += last.get(verdict.property) != value
            last[verdict.property] = value
    assert publisher.published == changes == zenoh_alone.stats.published - before
    assert publisher.last_sent == last


@given(steps=_DECIDED)
def test_elsewhere_every_decided_verdict_goes_out_in_order(steps):
    from rasm.logs import RepeatedLogs
    from rasm.platform.verdicts_out import VerdictPublisher

    bus = open_transport("local")
    bus.connect()
    sent: list = []
    bus.subscribe("#", lambda message: sent.append((message.topic, message.payload)))
    publisher = VerdictPublisher(bus, ["near", "far"], ros=False, skip={"foreign"},
                                 logs=RepeatedLogs())
    tc = _checker(steps)
    tc.batch_observers.append(publisher.publish_all)  # as the platform wires it
    expected = []
    for _ in steps:
        expected += [(f"rasm/verdict/{v.property}",
                      {"value": v.value is True and v.error is None, "time": v.time})
                     for v in tc.observe(0.0, {})
                     if v.value is not None and v.property != "foreign"]
    bus.close()
    assert sent == expected and publisher.published == len(expected)


def test_a_ros_verdict_that_could_not_be_sent_goes_out_with_the_next_one():
    from rasm.logs import RepeatedLogs
    from rasm.platform.verdicts_out import VerdictPublisher
    from rasm.properties.monitor import Verdict
    from rasm.ros2 import ZenohTransport
    from rasm.testing.servers import free_port

    port = free_port()
    transport = ZenohTransport(f"zenoh://127.0.0.1:{port}", listen=[f"tcp/127.0.0.1:{port}"])
    publisher = VerdictPublisher(transport, ["near"], ros=True, skip=(), logs=RepeatedLogs())
    publisher.publish_all([Verdict("near", 0, 0.0, False)])  # not connected yet: not sent
    assert publisher.published == 0 and publisher.last_sent == {}
    transport.connect()
    try:
        publisher.publish_all([Verdict("near", 1, 1.0, False)])  # the same value, sent now
        publisher.publish_all([Verdict("near", 2, 2.0, False)])
    finally:
        transport.close()
    assert publisher.published == 1 == transport.stats.published
    assert publisher.last_sent == {"near": False}
