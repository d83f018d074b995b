"""`rasm run` as the managing side of a ROS 2 system: foreign peers (eclipse-zenoh, cyclonedds
and rosbags only, tests/ros2/peer.py) publish the robot's topics and subscribe to what rasm
sends, over real Zenoh sessions and Cyclone DDS participants on loopback."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rasm.testing.servers import free_port
from tests.ros2.conftest import CYCLONE_LOOPBACK, DATA, wait_until

GUARD = DATA / "guard"
GUARD_MSG = [[str(GUARD / "msg" / "GuardState.msg"), "guard"]]

# what the robot publishes: driving at 0.8 m/s with something 0.4 m ahead
ODOM = {"header": {"frame_id": "odom"}, "pose": {"pose": {"position": {"x": 1.5}}},
        "twist": {"twist": {"linear": {"x": 0.8}}}}
SCAN = {"header": {"frame_id": "base_scan"}, "angle_increment": 0.0175, "range_max": 8.0,
        "ranges": [0.4, 1.0, float("inf"), 2.5]}
ROBOT = [
    {"topic": "/odom", "type": "nav_msgs/msg/Odometry", "messages": [ODOM], "stamp": True},
    {"topic": "/scan", "type": "sensor_msgs/msg/LaserScan", "messages": [SCAN]},
    {"topic": "/bumper", "type": "std_msgs/msg/Bool", "messages": [{"data": False}]},
]
# what rasm sends: the guard's actions and its verdicts
SENT = [
    {"topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist"},
    {"topic": "/guard_state", "type": "guard/msg/GuardState"},
    {"topic": "/rasm/verdict/speed_limit", "type": "std_msgs/msg/Bool"},
    {"topic": "/rasm/verdict/slow_near_obstacles", "type": "std_msgs/msg/Bool"},
]


def rasm_run(app: Path, transport: str, cwd: Path, *extra: str) -> subprocess.Popen:
    env = dict(os.environ, CYCLONEDDS_URI=CYCLONE_LOOPBACK, PYTHONUNBUFFERED="1")
    return subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--transport", transport, *extra],
        cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )


def finish(process: subprocess.Popen, timeout: float = 60) -> tuple[int, str]:
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        raise AssertionError(f"rasm run did not end: {out}\n{err}") from None
    return process.returncode, out + err


def network(peers, middleware: str):
    """A publishing and a subscribing peer, and the transport URL rasm joins them by."""
    if middleware == "zenoh":
        a, b = free_port(), free_port()
        robot = peers({"middleware": "zenoh", "role": "pub", "listen": f"tcp/127.0.0.1:{a}",
                       "repeat": True, "topics": ROBOT})
        robot.wait_for(lambda p: p.events, what="the robot peer to listen")
        watcher = peers({"middleware": "zenoh", "role": "sub", "listen": f"tcp/127.0.0.1:{b}",
                         "connect": [f"tcp/127.0.0.1:{a}"], "msg": GUARD_MSG, "topics": SENT})
        return robot, watcher, f"zenoh://127.0.0.1:{a}"
    domain = int.from_bytes(os.urandom(1), "big") % 200 + 20
    robot = peers({"middleware": "dds", "role": "pub", "domain": domain, "repeat": True,
                   "topics": ROBOT})
    watcher = peers({"middleware": "dds", "role": "sub", "domain": domain, "msg": GUARD_MSG,
                     "topics": SENT})
    return robot, watcher, f"dds://?domain={domain}"


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_rasm_run_reads_the_robots_topics_and_sends_actions_and_verdicts(
    peers, tmp_path, middleware
):
    robot, watcher, url = network(peers, middleware)
    watcher.wait_ready()
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(GUARD, url, tmp_path, "--duration", "6", "--trace", str(trace))
    robot.wait_ready()  # it publishes once rasm's subscriptions match
    cmd = watcher.wait_for(lambda p: p.messages("/cmd_vel"), timeout=30, what="a Twist")[0]
    state = watcher.wait_for(lambda p: p.messages("/guard_state"), timeout=30, what="a state")[0]
    watcher.wait_for(
        lambda p: p.messages("/rasm/verdict/slow_near_obstacles")
        and p.messages("/rasm/verdict/speed_limit"),
        timeout=30, what="verdicts",
    )
    code, output = finish(run)
    # the action payload filled the message fields the manifest maps, the rest is zero
    assert cmd["data"]["linear"] == {"x": 0.1, "y": 0.0, "z": 0.0}
    assert cmd["data"]["angular"] == {"x": 0.0, "y": 0.0, "z": 0.5}
    assert state["data"] == {"level": 2, "reason": "obstacle ahead"}
    # 0.8 m/s: within the speed limit, not slow enough with 0.4 m ahead
    assert {m["data"]["data"] for m in watcher.messages("/rasm/verdict/speed_limit")} == {True}
    assert False in {m["data"]["data"] for m in watcher.messages(
        "/rasm/verdict/slow_near_obstacles")}
    assert code == 1, output  # a property was violated
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    assert any(r.get("speed") == 0.8 for r in records)
    assert any(r.get("ahead") == pytest.approx(0.4) for r in records)
    assert any(r.get("bumped") is False for r in records)
    assert any(r.get("executed") for r in records)


ZERO_HASH = "RIHS01_" + "0" * 64


def _bad_utf8_scan() -> str:
    """A LaserScan whose frame_id is no UTF-8: well-formed CDR to Cyclone, malformed to ROS."""
    from rasm.ros2 import TypeStore

    data = TypeStore().codec("sensor_msgs/msg/LaserScan").encode(
        {"header": {"frame_id": "ab"}, "ranges": [0.1]})
    return data.replace(b"ab\0", b"\xff\xfe\0").hex()


FAST = {"twist": {"twist": {"linear": {"x": 9.0}}}}  # would show in the trace if taken


def hostile(middleware: str) -> tuple[list[dict], list[dict]]:
    """Two foreign publishers' topics: malformed CDR on /scan, Odometry with a wrong type hash
    on /odom and a type nobody knows on /bumper; a String on /scan (a topic with two types)."""
    if middleware == "zenoh":
        first = [
            {"topic": "/scan", "type": "sensor_msgs/msg/LaserScan", "raw": [_bad_utf8_scan()]},
            {"topic": "/odom", "type": "nav_msgs/msg/Odometry", "messages": [FAST],
             "key": f"0/odom/nav_msgs::msg::dds_::Odometry_/{ZERO_HASH}"},
            {"topic": "/bumper", "type": "std_msgs/msg/Bool", "messages": [{"data": True}],
             "key": f"0/bumper/foo_msgs::msg::dds_::Bar_/{ZERO_HASH}"},
        ]
    else:
        first = [
            {"topic": "/scan", "type": "sensor_msgs/msg/LaserScan", "raw": [_bad_utf8_scan()]},
            {"topic": "/odom", "type": "nav_msgs/msg/Odometry", "messages": [FAST],
             "type_hash": ZERO_HASH},
            {"topic": "/bumper", "type": "std_msgs/msg/Bool", "messages": [{"data": True}],
             "type_name": "foo_msgs::msg::dds_::Bar_", "wait": False},
        ]
    second = [{"topic": "/scan", "type": "std_msgs/msg/String", "messages": [{"data": "hi"}],
               "wait": False}]
    return first, second


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_bad_input_on_the_wire_is_counted_logged_once_and_never_stored(
    peers, tmp_path, middleware
):
    robot, _, url = network(peers, middleware)
    first, second = hostile(middleware)
    if middleware == "zenoh":
        meet = [f"tcp/127.0.0.1:{url.rsplit(':', 1)[1]}"]
        bad = [peers({"middleware": "zenoh", "role": "pub", "repeat": True, "connect": meet,
                      "listen": f"tcp/127.0.0.1:{free_port()}", "topics": topics})
               for topics in (first, second)]
    else:
        domain = int(url.rsplit("=", 1)[1])
        bad = [peers({"middleware": "dds", "role": "pub", "domain": domain, "repeat": True,
                      "topics": topics}) for topics in (first, second)]
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(GUARD, url, tmp_path, "--duration", "6", "--trace", str(trace))
    robot.wait_ready()
    for peer in bad:
        peer.wait_for(lambda p: sum(e["event"] == "published" for e in p.events) >= 5,
                      timeout=30, what="five rounds of bad input")
    code, output = finish(run)
    assert code in (0, 1) and "Traceback" not in output, output
    assert "'malformed messages':" in output  # counted in the run's summary
    # logged once per topic and reason, however often it came
    for topic, reason in [("/scan", "malformed"), ("/odom", "wrong hash"),
                          ("/bumper", "unknown type"), ("/scan", "type conflict")]:
        said = [line for line in output.splitlines()
                if f"ignored a message on {topic} ({reason})" in line]
        assert len(said) == 1, (topic, reason, output)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    # the robot's own messages went in; none of the bad ones did
    assert any(r.get("speed") == 0.8 for r in records)
    assert not any(r.get("speed") == 9.0 for r in records)
    assert not any(r.get("bumped") is True for r in records)
    assert [r["ahead"] for r in records if "ahead" in r] == pytest.approx([0.4] * len(
        [r for r in records if "ahead" in r]))


@pytest.mark.slow
def test_verdicts_go_out_when_they_change_and_a_late_subscriber_gets_the_current_one(
    peers, tmp_path
):
    robot, watcher, url = network(peers, "dds")
    watcher.wait_ready()
    run = rasm_run(GUARD, url, tmp_path, "--duration", "5")
    robot.wait_ready()
    watcher.wait_for(lambda p: p.messages("/rasm/verdict/slow_near_obstacles"), timeout=30,
                     what="a verdict")
    domain = int(url.rsplit("=", 1)[1])
    late = peers({"middleware": "dds", "role": "sub", "domain": domain, "topics": [
        {"topic": "/rasm/verdict/speed_limit", "type": "std_msgs/msg/Bool", "latched": True}]})
    late.wait_for(lambda p: p.messages(), timeout=30, what="the latched verdict")
    code, output = finish(run)
    assert code == 1, output
    # some 50 records judged at 0.8 m/s: speed_limit held throughout, said once
    assert [m["data"]["data"] for m in watcher.messages("/rasm/verdict/speed_limit")] == [True]
    assert [m["data"]["data"] for m in late.messages()] == [True]


ECHO = DATA / "echo"  # rasm both writes and reads /level and /push (its simulator runs in it)
# what each foreign participant publishes before it leaves: values the echo app never makes
FOREIGN = [{"topic": "/level", "type": "std_msgs/msg/Float64", "messages": [{"data": 5000.0}]},
           {"topic": "/push", "type": "std_msgs/msg/Float64", "messages": [{"data": 7000.0}]}]


def churn(peers, domain: int, trace: Path, rounds: int = 100):
    """Once the run's loop is going, a hundred Cyclone participants in another process come,
    read and publish on rasm's own topics and leave (the traffic that deadlocked a run whose
    listener ran Python on Cyclone's thread while a write held the GIL)."""
    wait_until(lambda: trace.exists() and '"executed"' in trace.read_text(), timeout=60,
               what="the loop to act")
    return peers({"middleware": "dds", "role": "churn", "domain": domain, "rounds": rounds,
                  "topics": FOREIGN})


@pytest.fixture
def runs():
    """``runs(process)``: the process, killed at teardown if still running (a hung run)."""
    started: list[subprocess.Popen] = []

    def keep(process: subprocess.Popen) -> subprocess.Popen:
        started.append(process)
        return process

    yield keep
    for process in started:
        if process.poll() is None:
            process.kill()
            process.communicate()


def rounds_done(peer, n: int) -> bool:
    return any(e["event"] == "round" and e["n"] >= n for e in list(peer.events))


@pytest.mark.slow
def test_foreign_participants_coming_publishing_and_leaving_never_stop_a_dds_run(
    peers, runs, tmp_path, dds_domain
):
    trace = tmp_path / "trace.jsonl"
    started = time.monotonic()
    run = runs(rasm_run(ECHO, f"dds://?domain={dds_domain}", tmp_path, "--duration", "20",
                        "--trace", str(trace)))
    foreign = churn(peers, dds_domain, trace)
    foreign.wait_for(lambda p: rounds_done(p, 100), timeout=60, what="a hundred participants")
    assert run.poll() is None, "the run ended before the participants were done"
    code, output = finish(run, timeout=60)
    # on time (20 s, and the start-up and shutdown of a loaded machine), with its summary
    assert time.monotonic() - started < 45, output
    assert code in (0, 1) and "Traceback" not in output, output
    assert "echo: 20 s on the wall clock" in output and "stopped by" not in output, output
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    # the participants' messages came in (and the loop pushed the level back after them)
    assert any(r.get("level") == 5000.0 for r in records)
    after = next(i for i, r in enumerate(records) if r.get("level") == 5000.0)
    assert any(r.get("executed") for r in records[after:])


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_a_dds_run_while_foreign_participants_come_and_go(
    peers, runs, tmp_path, dds_domain, signum
):
    trace = tmp_path / "trace.jsonl"
    run = runs(rasm_run(ECHO, f"dds://?domain={dds_domain}", tmp_path, "--duration", "120",
                        "--trace", str(trace)))
    foreign = churn(peers, dds_domain, trace, rounds=1000)
    foreign.wait_for(lambda p: rounds_done(p, 50), timeout=60, what="fifty participants")
    run.send_signal(signum)
    signalled = time.monotonic()
    code, output = finish(run, timeout=30)
    assert time.monotonic() - signalled < 20, output
    assert code in (0, 1) and "Traceback" not in output, (code, output)
    # the summary, saying what ended the run
    assert f"(stopped by {signal.Signals(signum).name})" in output, output
    assert "trace records" in output, output


@pytest.mark.slow
def test_messages_over_max_payload_never_reach_knowledge_or_the_trace(
    peers, runs, tmp_path, dds_domain
):
    # the attack in small: strings of 5 MB (before max_payload, 58 of 20 MB took 1.5 GB of
    # memory and a 1.1 GB trace); the foreign writer keeps them for a late reader (latched).
    # Cyclone, capped by the domain rasm makes, drops each as it arrives and says so.
    trace = tmp_path / "trace.jsonl"
    run = runs(rasm_run(ECHO, f"dds://?domain={dds_domain}", tmp_path, "--duration", "6",
                        "--trace", str(trace)))
    wait_until(lambda: trace.exists() and '"executed"' in trace.read_text(), timeout=60,
               what="the loop to act")
    notes = [{"topic": "/note", "type": "std_msgs/msg/String", "latched": True,
              "strings": [5 << 20] * 10, "messages": [{"data": "small"}]}]
    peers({"middleware": "dds", "role": "pub", "domain": dds_domain, "topics": notes})
    code, output = finish(run)
    assert code in (0, 1) and "Traceback" not in output, output
    assert output.count("dropping oversize (5242892 > 1048576)") == 10, output
    assert trace.stat().st_size < 2 << 20
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    assert [r["note"] for r in records if "note" in r] == ["small"]


@pytest.mark.slow
def test_an_action_beyond_its_field_s_range_fails_naming_why_and_the_loop_goes_on(tmp_path):
    trace = tmp_path / "trace.jsonl"
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(DATA / "wide"), "--duration", "5",
         "--clock", "simulated", "--trace", str(trace)],
        capture_output=True, text=True, timeout=120,
    )
    assert run.returncode in (0, 1) and "Traceback" not in run.stderr, run.stderr
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    dropped = [r["explanation"] for r in records if r.get("dropped")]
    executed = [r for r in records if r.get("executed")]
    assert len(dropped) == len(executed) == 5  # every other of ten iterations
    assert set(dropped) == {
        "effector unreachable: effector drive: field 'data' of std_msgs/msg/Float32: 1e+39 "
        "(float) is out of range for float32 (its largest finite value is "
        "3.4028234663852886e+38)"
    }
