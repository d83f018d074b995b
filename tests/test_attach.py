"""``rasm monitor``: monitors attached to a live bus, end to end over a real mosquitto."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time as clock
from pathlib import Path

import paho.mqtt.publish as paho_publish
import pytest

from rasm.attach import Attachment, SignedVerdicts, Source, default_topic_map, load_topic_map
from rasm.errors import CommError, SourceError
from tests.comm.support import Inbox

PROPS = """
input mode: str = "navigate"
event anomaly
property velocity_limit:
    always (velocity <= 0.5 or mode == "emergency")
property timely_adaptation:
    always (anomaly -> eventually[0, 2s] adapted)
"""


def test_verdicts_are_published_on_rasm_verdict_topics(mqtt):
    """SPEC §10: a verdict goes on rasm/verdict/<property>, where no app's effector is."""
    bus, robot = mqtt(), mqtt()
    limit, timely = Inbox(), Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    robot.subscribe("rasm/verdict/timely_adaptation", timely, qos=1)
    attachment = Attachment(PROPS, bus, qos=1).start()
    assert attachment.subscribed_topics == ["adapted", "anomaly", "mode", "rasm/trace", "velocity"]

    robot.publish("velocity", {"value": 0.3, "time": 1.0}, qos=1)
    assert limit.get().payload == {"value": True, "time": 1.0}
    robot.publish("velocity", {"value": 0.7, "time": 2.0}, qos=1)
    assert limit.get().payload == {"value": False, "time": 2.0}
    robot.publish("mode", {"mode": "emergency", "time": 2.5}, qos=1)  # the field named like it
    assert limit.get().payload == {"value": True, "time": 2.5}

    robot.publish("adapted", {"value": False, "time": 3.0}, qos=1)
    robot.publish("anomaly", {"value": True, "time": 3.0}, qos=1)
    robot.publish("adapted", {"value": True, "time": 4.0}, qos=1)
    robot.publish("adapted", {"value": False, "time": 6.5}, qos=1)  # closes the 2 s windows
    decided = [m.payload for m in timely.take(3)]
    assert {"value": True, "time": 3.0} in decided  # the anomaly at 3.0 was answered at 4.0
    assert all(v["value"] is True for v in decided)

    summary = attachment.stop()
    assert summary.records == 7 and summary.malformed == 0 and summary.rejected == 0
    assert summary.violated["velocity_limit"] == 1
    assert summary.first_violations == {"velocity_limit": 2.0}
    assert summary.any_violated
    assert "velocity_limit     violated     6 true, 1 false" in summary.format()


def test_the_public_checkers_topics_named_after_the_properties_are_an_option(mqtt):
    bus, robot = mqtt(), mqtt()
    bare, spec = Inbox(), Inbox()
    robot.subscribe("velocity_limit", bare, qos=1)
    robot.subscribe("rasm/verdict/velocity_limit", spec, qos=1)
    attachment = Attachment(PROPS, bus, verdict_topic="{property}", qos=1).start()
    robot.publish("velocity", {"value": 0.7, "time": 2.0}, qos=1)
    assert bare.get().payload == {"value": False, "time": 2.0}
    attachment.stop()
    assert spec.empty()  # only where the option says


@pytest.mark.parametrize(("template", "words"), [
    ("verdicts", "must name the property with {property}"),  # one topic for all: whose?
    ("{prop}{property}", "must be a topic with {property}"),
    ("{property}{", "must be a topic with {property}"),
    ("{property}/+", "wildcard"),
    ("robot/{property}", None),
    ("rasm/{property}", None),
    ("{property}", "which the monitor reads (velocity)"),  # a property named like a topic read
])
def test_a_verdict_topic_is_a_topic_of_its_own_for_each_property(mqtt, template, words):
    text = PROPS + "property velocity:\n    always (velocity < 2)\n"
    if words is None:
        Attachment(text, mqtt(), verdict_topic=template)
        return
    with pytest.raises(CommError) as caught:
        Attachment(text, mqtt(), verdict_topic=template)
    assert words in str(caught.value)


def test_the_summary_names_the_properties_satisfied_only_vacuously(mqtt):
    """As rasm run's summary: a property whose `->` was never put to the test is marked and
    what never happened is said."""
    bus, robot = mqtt(), mqtt()
    limit = Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    attachment = Attachment(PROPS, bus, qos=1).start()
    for time in (1.0, 2.0, 5.0):  # no anomaly ever
        robot.publish("rasm/trace", {"time": time, "velocity": 0.1, "adapted": False}, qos=1)
    assert len(limit.take(3)) == 3  # every record was stepped
    summary = attachment.stop()
    outcome = summary.outcome("timely_adaptation")
    assert outcome.state == "satisfied" and [u.text for u in outcome.vacuous] == ["anomaly"]
    assert summary.outcome("velocity_limit").vacuous == ()  # no ->: nothing left untested
    text = summary.format()
    assert "timely_adaptation  satisfied*   3 true" in text
    assert text.endswith(
        "* never put to the test:\n"
        "  timely_adaptation: satisfied (vacuously: anomaly never happened)\n"
    )
    assert "velocity_limit     satisfied    3 true" in text


def test_malformed_and_refused_messages_are_counted_never_fatal(mqtt, broker):
    bus, robot = mqtt(), mqtt()
    limit = Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    attachment = Attachment(PROPS, bus, qos=1).start()
    robot.publish("velocity", {"speed": 0.1, "time": 1.0}, qos=1)  # no mapped field
    robot.publish("velocity", {"value": 0.1, "time": "soon"}, qos=1)  # bad time
    robot.publish("velocity", {"value": "fast", "time": 1.0}, qos=1)  # wrong type
    robot.publish("velocity", {"value": 0.1, "time": 5.0}, qos=1)
    robot.publish("velocity", {"value": 0.1, "time": 4.0}, qos=1)  # back in time
    # a foreign, broken publisher (returns once the broker has it, so it arrives before the next)
    paho_publish.single("velocity", b"not json", qos=1, hostname=broker.host, port=broker.port)
    robot.publish("velocity", {"value": 0.2, "time": 6.0}, qos=1)
    assert [m.payload for m in limit.take(2)] == [
        {"value": True, "time": 5.0},
        {"value": True, "time": 6.0},
    ]
    summary = attachment.stop()
    # the summary counts the message the transport dropped (not JSON) with the two it ignored
    assert (summary.malformed, summary.rejected, summary.records) == (3, 2, 2)
    assert bus.stats.malformed == 1


def test_time_falls_back_to_the_envelope_timestamp(mqtt):
    bus, robot = mqtt(), mqtt()
    limit = Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    attachment = Attachment(PROPS, bus, qos=1).start()
    robot.publish("velocity", {"value": 0.1}, qos=1)
    message = limit.get()
    stamp = message.payload["time"]
    assert isinstance(stamp, float) and stamp <= message.timestamp
    attachment.stop()


def test_a_topic_map_moves_signals_and_fields(mqtt, tmp_path):
    path = tmp_path / "topics.yaml"
    path.write_text(
        "velocity: robot/odometry\nmode: {topic: robot/state, field: mode}\n"
        "anomaly: {topic: robot/state, field: alarm}\n"
    )
    signals = ["velocity", "mode", "anomaly", "adapted"]
    mapping = load_topic_map(path, signals)
    assert mapping == {
        "velocity": Source("velocity", "robot/odometry"),
        "mode": Source("mode", "robot/state", "mode"),
        "anomaly": Source("anomaly", "robot/state", "alarm"),
        "adapted": Source("adapted", "adapted"),
    }
    bus, robot = mqtt(), mqtt()
    limit = Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    attachment = Attachment(PROPS, bus, topics=mapping, qos=1).start()
    robot.publish("robot/odometry", {"value": 0.9, "time": 1.0}, qos=1)
    assert limit.get().payload == {"value": False, "time": 1.0}
    robot.publish("robot/state", {"mode": "emergency", "alarm": False, "time": 2.0}, qos=1)
    assert limit.get().payload == {"value": True, "time": 2.0}
    attachment.stop()


@pytest.mark.parametrize(
    ("text", "message", "line"),
    [
        ("speed: robot/odom\n", "'speed' is not a signal the properties read", 1),
        ("velocity: robot/#\n", "velocity", 1),
        ("mode: x\nvelocity: {topic: a, unit: m}\n", "write a topic", 2),
        ("velocity: [a\n", "YAML syntax error", 2),
        ("- velocity\n", "a topic map is a mapping", 1),
    ],
)
def test_bad_topic_maps_name_the_place(text, message, line):
    with pytest.raises(SourceError, match=message) as caught:
        load_topic_map("map.yaml", ["velocity", "mode"], text=text)
    assert caught.value.location.file == "map.yaml"
    assert caught.value.location.line == line


def test_default_map():
    assert default_topic_map(["v"]) == {"v": Source("v", "v")}
    assert Source("v", "t").extract({"v": 1, "value": 2}) == (True, 2)
    assert Source("v", "t").extract({"v": 1}) == (True, 1)
    assert Source("v", "t", "f").extract({"v": 1}) == (False, None)


def test_the_command_runs_until_interrupted_and_summarises(broker, mqtt, tmp_path):
    props = tmp_path / "props.rv"
    props.write_text(PROPS)
    process = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        ready = process.stderr.readline()
        assert ready.startswith("rasm monitor: 2 properties on 5 topic(s)"), ready
        robot = mqtt()
        limit = Inbox()
        robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
        # epoch times: written as the decimals they are (1700000002.3, not 1.7e+09)
        for time, value in ((1700000001.1, 0.2), (1700000002.3, 0.8), (1700000003.0, 0.1)):
            robot.publish("velocity", {"value": value, "time": time}, qos=0)
        assert [m.payload["value"] for m in limit.take(3)] == [True, False, True]
        robot.publish("velocity", {"value": 0.1, "time": 0.5}, qos=0)  # refused, not fatal
        robot.publish("velocity", {"value": 0.1, "time": 1700000004.0}, qos=0)
        assert limit.get().payload == {"value": True, "time": 1700000004.0}
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 1, err  # a property was violated
    assert out.splitlines()[0] == "violated velocity_limit at t=1700000002.3"
    assert "5 message(s), 4 record(s)" in out and "1 refused by the monitor" in out
    assert "velocity_limit     violated     3 true, 1 false" in out
    assert "(first violation at t=1700000002.3)" in out


def test_the_command_reports_bad_input(broker, tmp_path):
    props = tmp_path / "props.rv"
    props.write_text("property p:\n    always (velocity <=)\n")
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and f"{props}:2:" in done.stderr
    props.write_text(PROPS)
    topics = tmp_path / "map.yaml"
    topics.write_text("nope: x\n")
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "rasm.cli",
            "monitor",
            str(props),
            "--transport",
            broker.url,
            "--topics",
            str(topics),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and f"{topics}:1:1: 'nope' is not a signal" in done.stderr
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", "bogus://x"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and "bad transport URL" in done.stderr
    for option, env, words in [
        (["--verdict-topic", "verdicts"], {}, "must name the property with {property}"),
        (["--verdict-topic", "{property}/#"], {}, "contains a wildcard"),
        ([], {"RASM_ACTION_KEY": "not hex"}, "RASM_ACTION_KEY must be the signing key in hex"),
    ]:
        done = subprocess.run(
            [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url,
             *option],
            capture_output=True, text=True, timeout=60, env={**os.environ, **env},
        )
        assert done.returncode == 2 and words in done.stderr, (option, done.stderr)
        assert "Traceback" not in done.stderr
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", "zenoh://127.0.0.1:1"],
        capture_output=True, text=True, timeout=60, env={**os.environ, "RASM_ACTION_KEY": "ab"},
    )
    assert done.returncode == 2 and "RASM_ACTION_KEY signs verdicts over MQTT" in done.stderr


NEW_PROPS = """
property slow:
    always (speed <= 2)
"""


def test_signed_property_updates_replace_the_monitors(mqtt):
    from rasm.comm import BoundSigner, UpdateReceiver

    key = b"operator key"
    bus, operator = mqtt(), mqtt()
    limit, slow, results = Inbox(), Inbox(), Inbox()
    operator.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    operator.subscribe("rasm/verdict/slow", slow, qos=1)
    operator.subscribe("rasm/update/result", results, qos=1)
    attachment = Attachment(PROPS, bus, qos=1).start()
    receiver = UpdateReceiver(bus, key, properties=attachment.replace).start()
    signer = BoundSigner(key)

    def sign(payload: dict, key: bytes) -> dict:
        return signer.sign(payload, topic="rasm/update/properties", epochs=[receiver.epoch])

    operator.publish("rasm/update/properties", {"spec": NEW_PROPS}, qos=1)
    assert results.get().payload["reason"] == "unsigned"
    operator.publish("rasm/update/properties", sign({"spec": "property p: always ("}, key), qos=1)
    refused = results.get().payload
    assert refused["accepted"] is False and "the new file does not load" in refused["reason"]
    operator.publish("velocity", {"value": 0.9, "time": 1.0}, qos=1)
    assert limit.get().payload == {"value": False, "time": 1.0}  # still the old properties

    operator.publish("rasm/update/properties", sign({"spec": NEW_PROPS}, key), qos=1)
    accepted = results.get().payload
    assert accepted["accepted"] is True and accepted["reason"].endswith(": slow")
    assert attachment.subscribed_topics == ["rasm/trace", "speed"]
    operator.publish("speed", {"value": 3, "time": 2.0}, qos=1)
    assert slow.get().payload == {"value": False, "time": 2.0}
    summary = attachment.stop()
    assert summary.properties == ["velocity_limit", "timely_adaptation", "slow"]
    assert summary.violated == {"velocity_limit": 1, "slow": 1}


def test_a_whole_trace_on_one_topic(mqtt):
    """``"*": rasm/trace``: every unmapped signal is the field of its name on one topic, so a
    loop that publishes its trace records there is monitored as `rasm check` reads the file."""
    mapping = load_topic_map(
        "map.yaml",
        ["velocity", "mode", "anomaly", "adapted"],
        text='"*": rasm/trace\nmode: {topic: robot/state, field: mode}\n',
    )
    assert mapping["velocity"] == Source("velocity", "rasm/trace", "velocity")
    assert mapping["mode"] == Source("mode", "robot/state", "mode")
    bus, loop = mqtt(), mqtt()
    limit, timely = Inbox(), Inbox()
    loop.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    loop.subscribe("rasm/verdict/timely_adaptation", timely, qos=1)
    attachment = Attachment(PROPS, bus, topics=mapping, qos=1).start()
    assert attachment.subscribed_topics == ["rasm/trace", "robot/state"]
    records = [
        {"time": 0.0, "velocity": 0.2, "adapted": False},
        {"time": 1.0, "velocity": 0.9, "anomaly": True},
        {"time": 1.5, "adapted": True},
        {"time": 4.0, "velocity": 0.1},
    ]
    for record in records:
        loop.publish("rasm/trace", record, qos=1)
    # velocity is held at 0.9 on the record at 1.5 (sample-and-hold)
    assert [m.payload["value"] for m in limit.take(4)] == [True, False, False, True]
    assert {"value": True, "time": 1.0} in [m.payload for m in timely.take(3)]
    # a property update may read a new signal: it comes from the "*" topic too
    ok, _ = attachment.replace("property quick: always (latency <= 1)")
    assert ok and attachment.subscribed_topics == ["rasm/trace"]
    quick = Inbox()
    loop.subscribe("rasm/verdict/quick", quick, qos=1)
    loop.publish("rasm/trace", {"time": 5.0, "latency": 3}, qos=1)
    loop.publish("rasm/trace", {"time": 6.0, "latency": 0.5}, qos=1)
    assert [m.payload for m in quick.take(2)] == [
        {"value": False, "time": 5.0},
        {"value": True, "time": 6.0},
    ]
    attachment.stop()


def test_an_update_replayed_into_a_restarted_monitor_process_is_refused(broker, mqtt, tmp_path):
    """``rasm monitor`` with RASM_UPDATE_KEY announces the epoch updates must be bound to; the
    update one process accepted is refused by the next one, which accepts a newly bound one."""
    from rasm.comm import BoundSigner, PresenceTracker

    key = "d4" * 16
    props = tmp_path / "props.rv"
    props.write_text(PROPS)
    operator = mqtt()
    results, online = Inbox(), Inbox()
    operator.subscribe("rasm/update/result", results, qos=1)
    tracker = PresenceTracker(
        operator, on_change=lambda node, state: state == "online" and online(node)
    ).start()
    signer = BoundSigner(bytes.fromhex(key))

    def monitor() -> tuple[subprocess.Popen, str]:
        process = subprocess.Popen(
            [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "RASM_UPDATE_KEY": key},
        )
        assert online.get(timeout=30) == f"monitor-{process.pid}"
        return process, tracker.epochs(role="monitor")[f"monitor-{process.pid}"]

    def send(update: dict) -> dict:
        operator.publish("rasm/update/properties", update, qos=1)
        return results.get().payload

    def stop(process: subprocess.Popen) -> str:
        process.send_signal(signal.SIGINT)
        out, _ = process.communicate(timeout=30)
        return out

    processes = []
    try:
        first, epoch = monitor()
        processes.append(first)
        update = signer.sign({"spec": NEW_PROPS}, topic="rasm/update/properties", epochs=[epoch])
        assert send(update)["accepted"] is True
        assert "slow" in stop(first)

        second, new_epoch = monitor()
        processes.append(second)
        assert new_epoch != epoch
        replayed = send(update)
        assert replayed["accepted"] is False
        assert "signed for another incarnation" in replayed["reason"]
        assert replayed["epoch"] == new_epoch  # the answer says what to bind to instead
        rebound = signer.sign(
            {"spec": NEW_PROPS}, topic="rasm/update/properties", epochs=[new_epoch]
        )
        assert send(rebound)["accepted"] is True
        assert "slow" in stop(second)
    finally:
        tracker.stop()
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait()


def test_a_property_whose_signal_never_arrives_is_not_judged_and_fails(mqtt, broker, tmp_path):
    bus, robot = mqtt(), mqtt()
    limit = Inbox()
    robot.subscribe("rasm/verdict/velocity_limit", limit, qos=1)
    text = PROPS + "property steady:\n    always (heading <= 90)\n"
    attachment = Attachment(text, bus, qos=1).start()
    robot.publish("velocity", {"value": 0.3, "time": 1.0}, qos=1)
    assert limit.get().payload == {"value": True, "time": 1.0}
    summary = attachment.stop()
    steady = summary.outcome("steady")
    assert steady.state == "not judged" and steady.missing == ("heading",)
    # timely_adaptation reads `adapted`, which is no declared event (no default): never sent
    assert summary.failed == ["timely_adaptation", "steady"] and not summary.any_violated
    assert summary.outcome("timely_adaptation").missing == ("adapted",)
    line = "steady             not judged   0 true, 0 false, 0 inconclusive (no value for heading)"
    assert line in summary.format()
    # the command exits 1 for it, as for a violation
    props = tmp_path / "props.rv"
    props.write_text(text)
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url,
         "--duration", "0.5"],
        capture_output=True, text=True, timeout=60,
    )
    assert done.returncode == 1, done.stderr
    assert "(no value for heading)" in done.stdout


OVERFLOW = """
input x: float
input y: float
property budget:
    always (sum[0, 5s](x) <= 1e300)
property calm:
    always (y <= 1)
"""


def test_two_readings_of_1e308_never_give_a_satisfied_budget_and_the_monitor_recovers(mqtt):
    """Whether the overflowed sum makes the monitor raise (its properties are then in error
    and published so) or saturates (violated): every record gets a published verdict of every
    property, never a true one for the overflowed window, and true ones again after it."""
    bus, robot = mqtt(), mqtt()
    budget, calm = Inbox(), Inbox()
    robot.subscribe("rasm/verdict/budget", budget, qos=1)
    robot.subscribe("rasm/verdict/calm", calm, qos=1)
    attachment = Attachment(OVERFLOW, bus, qos=1).start()
    sent = [("y", 0.5, 0.0), ("x", 1.0, 0.5), ("x", 1e308, 1.0), ("x", 1e308, 2.0),
            ("y", 0.5, 2.5), ("x", 1.0, 3.0)] + [("x", 1.0, t) for t in (4.0, 5.0, 6.0, 7.0, 8.0)]
    for signal_, value, time in sent:
        robot.publish(signal_, {"value": value, "time": time}, qos=1)
    judged = sent[1:]  # budget waits for x; calm starts at once
    budgets = [m.payload for m in budget.take(len(judged))]
    calms = [m.payload for m in calm.take(len(sent))]
    summary = attachment.stop()
    assert [b["time"] for b in budgets] == [t for *_, t in judged]
    assert [c["time"] for c in calms] == [t for *_, t in sent]
    by_time = dict(zip([t for *_, t in judged], budgets, strict=True))
    for time in (2.0, 2.5, 3.0, 6.0):  # both readings in the window: the sum overflows
        assert by_time[time]["value"] is False, by_time[time]
        if "error" in by_time[time]:
            assert "Overflow" in by_time[time]["error"] or "overflow" in by_time[time]["error"]
    assert by_time[8.0] == {"value": True, "time": 8.0}  # the readings left the window
    # calm is judged on every record: true, or in error while its file's monitor could not tell
    assert all(c["value"] is True or "error" in c for c in calms)
    assert calms[-1] == {"value": True, "time": 8.0}
    assert summary.outcome("budget").state in ("violated", "error")
    assert "budget" in summary.failed


@pytest.mark.slow
def test_with_no_topic_map_a_rasm_loop_is_monitored_from_its_trace_topic(broker, mqtt, tmp_path):
    """A rasm loop on a broker publishes its trace on rasm/trace: an attachment with no topic
    map (what `rasm monitor` builds without --topics) reads it, every record counts (stage
    records too, none malformed), and the verdicts are those of `rasm check` on the file."""
    root = Path(__file__).resolve().parents[1]
    props = root / "examples" / "hotbox" / "properties" / "hotbox.rv"
    attachment = Attachment(props.read_text(), mqtt(), source=str(props), qos=1).start()
    assert "rasm/trace" in attachment.subscribed_topics
    trace = tmp_path / "trace.jsonl"
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(root / "examples" / "hotbox"),
         "--transport", broker.url, "--clock", "simulated", "--seed", "1",
         "--duration", "20", "--trace", str(trace)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    lines = trace.read_text().splitlines()
    # every reading of the simulator (one each 0.1 s, 0 to 20 s) crossed the broker
    assert sum("temperature" in json.loads(line) for line in lines) == 201
    records = len(lines)
    deadline = clock.monotonic() + 30
    while attachment.summary.messages < records and clock.monotonic() < deadline:
        clock.sleep(0.05)  # waiting for a condition: the messages the loop published to arrive
    summary = attachment.stop()
    assert (summary.messages, summary.records) == (records, records)
    assert summary.malformed == 0 and summary.rejected == 0
    checked = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "check", str(props), str(trace), "--format", "json"],
        capture_output=True, text=True, timeout=60,
    )
    offline = {p["name"]: (p["verdict"], p["judged"]) for p in json.loads(checked.stdout)[
        "properties"]}
    online = {name: (o.state, o.judged) for name, o in summary.outcomes.items()}
    assert online == offline and set(online) >= {"temperature_band", "back_to_normal"}


# ------------------------------------------- rasm monitor as a loop's external verdict source

CALM = """
input speed: float
property calm:
    always (speed <= 1.0)
"""

CALM_SOURCE = """
  external_verdicts:
    calm: {topic: rasm/verdict/calm, freshness: 0.5}
"""


class _Liar:
    """An outsider without the key: says "true" on the source's topic at 50 Hz, unsigned."""

    def __init__(self, transport):
        self.transport, self.sent = transport, 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(0.02):
            self.transport.publish("rasm/verdict/calm", {"value": True, "time": 0.0})
            self.sent += 1

    def close(self):
        self.stop.set()
        self.thread.join()


def _monitored_run(broker, mqtt, tmp_path, key, *, fast):
    """`rasm monitor` (with ``key``) started, then a loop with the key run for 3 s beside an
    outsider's unsigned trues; returns the loop's platform, summary and records, and the
    monitor's exit code and output."""
    from rasm import Platform, RunOptions
    from tests.platform.guarded import write_guarded_app

    folder = tmp_path / ("fast" if fast else "slow")
    app = write_guarded_app(folder / "app", period=0.1, veto=())
    (app / "app.yaml").write_text((app / "app.yaml").read_text() + CALM_SOURCE)
    props = folder / "calm.rv"
    props.write_text(CALM)
    monitor = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", broker.url],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "RASM_ACTION_KEY": key},
    )
    liar = _Liar(mqtt())
    try:
        ready = monitor.stderr.readline()
        assert "verdicts on rasm/verdict/<property>, signed for the loops" in ready, ready
        platform = Platform(app, RunOptions(
            transport=broker.url,
            clock="wall",
            knowledge="memory",
            state_dir=folder / "state",
            role="all",
            scenario={"fast": [[0, 100]]} if fast else {},
        ))
        records: list[dict] = []
        platform.on_record.append(lambda t, r: records.append({"time": t, **r}))
        summary = platform.run(3.0)
        monitor.send_signal(signal.SIGINT)
        out, err = monitor.communicate(timeout=30)
    finally:
        liar.close()
        if monitor.poll() is None:
            monitor.kill()
            monitor.wait()
    return platform, summary, records, liar.sent, monitor.returncode, out + err


@pytest.mark.slow
def test_a_loop_with_the_action_key_takes_rasm_monitor_as_its_external_verdict_source(
    broker, mqtt, tmp_path, monkeypatch
):
    """`rasm monitor` with RASM_ACTION_KEY signs its verdicts for the loops on the bus: the
    loop's source counts them (its trues let actions through, its falses veto every one), and
    an outsider's unsigned trues beside them are refused, clearing nothing."""
    key = "5a" * 32
    monkeypatch.setenv("RASM_ACTION_KEY", key)

    platform, summary, records, lies, code, output = _monitored_run(
        broker, mqtt, tmp_path, key, fast=False
    )
    assert summary.verdicts["calm"] == "satisfied"  # the monitor's signed trues were taken
    assert [r for r in records if r.get("executed")], "the monitor's trues let the loop act"
    refused = platform.managing.external_verdicts.refused["calm"]
    assert 0 < refused <= lies  # the outsider's, none of the monitor's
    assert code == 0 and "calm  satisfied" in output and "not sent" not in output

    platform, summary, records, lies, code, output = _monitored_run(
        broker, mqtt, tmp_path, key, fast=True
    )
    refused = platform.managing.external_verdicts.refused
    assert summary.verdicts["calm"] == "violated", (output[-3000:], refused, lies)
    assert not [r for r in records if r.get("executed")]  # whatever the outsider said
    dropped = [r for r in records if r.get("dropped")]
    assert dropped and all("calm" in r["explanation"] for r in dropped)
    assert 0 < refused["calm"] <= lies
    assert code == 1 and "calm  violated" in output


def test_signed_verdicts_are_bound_to_the_loops_that_introduced_themselves(mqtt):
    """The seal binds each verdict to the managing processes that introduced themselves with a
    correctly signed presence message: none yet, and the verdict is not sent (counted); a
    forged (unsigned) loop is never bound to; a loop gone offline no longer is."""
    from rasm.comm import BoundSigner, Presence, SignedGate

    key = bytes.fromhex("6b" * 32)
    bus, robot, loop_side = mqtt(), mqtt(), mqtt()
    calm = Inbox()
    robot.subscribe("rasm/verdict/calm", calm, qos=1)
    seal = SignedVerdicts(bus, key).start()
    attachment = Attachment(CALM, bus, seal=seal, qos=1).start()
    try:
        robot.publish("speed", {"value": 0.5, "time": 1.0}, qos=1)
        deadline = clock.monotonic() + 30
        while attachment.summary.unsent < 1 and clock.monotonic() < deadline:
            clock.sleep(0.01)  # waiting for a condition: the record to be stepped
        assert attachment.summary.unsent == 1 and calm.empty()

        forged = Presence(robot, "liar", role="all", info={"app": "x", "epoch": "e" * 32}).start()
        gate = SignedGate(key)  # the loop's: its epoch is what verdicts must be bound to
        loop = Presence(loop_side, "loop", role="all", info={"app": "x", "epoch": gate.epoch},
                        signer=BoundSigner(key)).start()
        deadline = clock.monotonic() + 30
        while not seal.epochs() and clock.monotonic() < deadline:
            clock.sleep(0.01)  # waiting for a condition: the loop's introduction to arrive
        assert seal.epochs() == [gate.epoch]  # the forged node is not among them
        robot.publish("speed", {"value": 2.0, "time": 2.0}, qos=1)
        payload = calm.get().payload
        assert payload["value"] is False and payload["binding"]["epochs"] == [gate.epoch]
        assert gate.check(payload, "rasm/verdict/calm") is None  # what the loop admits
        assert gate.check(payload, "rasm/verdict/calm") is not None  # once

        loop.stop()  # offline: not bound to any more
        deadline = clock.monotonic() + 30
        while seal.epochs() and clock.monotonic() < deadline:
            clock.sleep(0.01)  # waiting for a condition: the shutdown message to arrive
        assert seal.epochs() == []
        forged.stop()
    finally:
        summary = attachment.stop()
        seal.stop()
    assert summary.published == 1 and "1 not sent (no loop to bind them to)" in summary.format()
