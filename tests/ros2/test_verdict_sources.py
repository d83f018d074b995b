"""Only the declared publisher speaks for an external verdict over ROS 2: `rasm run` against a
real robot peer, a real monitor node (/monitor) and an outsider node, each its own Zenoh session
or Cyclone DDS participant (tests/ros2/peer.py, without rasm). An outsider's `true` clears no
veto, with no monitor running or beside the monitor's `false`; the monitor's own `true` does."""

from __future__ import annotations

import json
import os

import pytest

from rasm.testing.servers import free_port
from tests.ros2.conftest import DATA
from tests.ros2.test_run import ROBOT, finish, rasm_run

MONITORED = DATA / "guard" / "monitored.yaml"


def _verdicts(value: bool) -> list[dict]:
    return [{"topic": "/monitor/ok", "type": "std_msgs/msg/Bool", "messages": [{"data": value}]}]


def _start(peers, middleware, nodes):
    """The robot peer, then one peer per (node, value) publishing /monitor/ok again and
    again; returns the transport URL rasm joins them by, and the started peers."""
    if middleware == "zenoh":
        port = free_port()
        robot = peers({"middleware": "zenoh", "role": "pub", "listen": f"tcp/127.0.0.1:{port}",
                       "repeat": True, "topics": ROBOT})
        robot.wait_for(lambda p: p.events, what="the robot peer to listen")
        common = {"middleware": "zenoh", "connect": [f"tcp/127.0.0.1:{port}"]}
        url = f"zenoh://127.0.0.1:{port}"
    else:
        domain = int.from_bytes(os.urandom(1), "big") % 200 + 20
        robot = peers({"middleware": "dds", "role": "pub", "domain": domain, "repeat": True,
                       "topics": ROBOT})
        common = {"middleware": "dds", "domain": domain}
        url = f"dds://?domain={domain}"
    started = [robot]
    for node, value in nodes:
        config = {**common, "role": "pub", "repeat": True, "node": node,
                  "topics": _verdicts(value)}
        if middleware == "zenoh":
            config["listen"] = f"tcp/127.0.0.1:{free_port()}"
        started.append(peers(config))
    return url, started


def _run(url, peers_started, tmp_path):
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(MONITORED, url, tmp_path, "--duration", "4", "--trace", str(trace))
    for peer in peers_started:
        peer.wait_ready()
    code, output = finish(run)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    return code, output, records


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_an_outsiders_true_with_no_monitor_running_clears_no_veto(peers, tmp_path, middleware):
    url, started = _start(peers, middleware, [("/outsider", True)])
    code, output, records = _run(url, started, tmp_path)
    assert code == 1, output
    assert not [r for r in records if r.get("executed")], output
    dropped = [r for r in records if r.get("dropped")]
    assert dropped and all("monitor_ok not judged yet" in r["explanation"] for r in dropped)
    assert "foreign publisher" in output and "/outsider" in output


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_an_outsiders_true_beside_the_monitors_false_clears_no_veto(peers, tmp_path, middleware):
    url, started = _start(peers, middleware, [("/monitor", False), ("/outsider", True)])
    code, output, records = _run(url, started, tmp_path)
    assert code == 1, output
    assert not [r for r in records if r.get("executed")], output
    dropped = [r for r in records if r.get("dropped")]
    assert dropped and any("veto property monitor_ok violated" in r["explanation"]
                           for r in dropped), output


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_the_declared_monitors_true_lets_actions_through_whatever_an_outsider_says(
    peers, tmp_path, middleware
):
    url, started = _start(peers, middleware, [("/monitor", True), ("/outsider", False)])
    code, output, records = _run(url, started, tmp_path)
    assert [r for r in records if r.get("executed")], output
    assert "foreign publisher" in output and "/outsider" in output


WATCHED = DATA / "guard" / "watched.yaml"


@pytest.mark.slow
@pytest.mark.parametrize("middleware", ["zenoh", "dds"])
def test_a_dead_robot_is_lost_and_nothing_is_judged_on_its_last_reading(
    peers, tmp_path, middleware
):
    from tests.ros2.conftest import wait_until

    # the robot is node /robot; it dies once rasm has acted on it
    if middleware == "zenoh":
        port = free_port()
        robot = peers({"middleware": "zenoh", "role": "pub", "listen": f"tcp/127.0.0.1:{port}",
                       "repeat": True, "node": "/robot", "topics": ROBOT})
        robot.wait_for(lambda p: p.events, what="the robot peer to listen")
        url = f"zenoh://127.0.0.1:{port}"
    else:
        domain = int.from_bytes(os.urandom(1), "big") % 200 + 20
        robot = peers({"middleware": "dds", "role": "pub", "domain": domain, "repeat": True,
                       "node": "/robot", "topics": ROBOT})
        url = f"dds://?domain={domain}"
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(WATCHED, url, tmp_path, "--duration", "8", "--trace", str(trace))
    robot.wait_ready()

    def acted():
        text = trace.read_text() if trace.exists() else ""
        return any(json.loads(line).get("executed") for line in text.splitlines())

    wait_until(acted, timeout=30, what="rasm to act on the robot")
    robot.stop()
    code, output = finish(run)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    assert code == 1, output
    lost = next(r for r in records if "managed_system_lost" in str(r.get("explanation")))
    assert "probe /odom" in lost["explanation"], lost
    assert [r["fallback"] for r in records if "fallback" in r][:1] == ["engaged"]
    # nothing but the fallback's stop was tried after the loss, and it found nobody
    after = [r for r in records if r["time"] >= lost["time"] and r.get("executed")]
    assert not after, after
    # speed_limit held while the robot was there; on its last reading it is not "satisfied"
    assert "not judged on a stale reading" in output, output
