"""Service and action effectors in `rasm run`: the action path through the Trustworthiness
Checker to a call, answers into knowledge, failures in the trace and the summary, goals
cancelled when a veto closes or the fallback engages. The robot is peers written with
eclipse-zenoh and rosbags alone (tests/ros2/peer.py: a heartbeat publisher, a server of
test_msgs' BasicTypes service and Fibonacci action), through a router configured as rmw_zenohd."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from ruamel.yaml import YAML

from tests.ros2.conftest import DATA
from tests.ros2.test_interfaces import TEST_INTERFACES
from tests.ros2.test_replay import read_mcap
from tests.ros2.test_run import finish, rasm_run

pytestmark = pytest.mark.skipif(not TEST_INTERFACES.is_dir(),
                                reason="Debian's ros2-test-interface-files is not installed")

BEAT = [{"topic": "/beat", "type": "std_msgs/msg/Int32", "messages": [{"data": 1}]}]


def calls_app(tmp_path: Path, change=None) -> Path:
    """The calls app in a folder named test_msgs, with test_msgs' BasicTypes.srv and
    Fibonacci.action (so its types are test_msgs', as the server's); ``change(manifest)``
    edits its app.yaml."""
    app = tmp_path / "test_msgs"
    shutil.copytree(DATA / "calls", app)
    (app / "srv").mkdir()
    (app / "action").mkdir()
    shutil.copy(TEST_INTERFACES / "srv" / "BasicTypes.srv", app / "srv")
    shutil.copy(TEST_INTERFACES / "action" / "Fibonacci.action", app / "action")
    if change is not None:
        manifest = YAML(typ="safe").load((app / "app.yaml").read_text())
        change(manifest)
        (app / "app.yaml").write_text(json.dumps(manifest))  # JSON is YAML
    return app


def robot(peers, router: int, **server):
    """The heartbeat publisher and, with ``server`` settings, the service/action server."""
    connect = [f"tcp/127.0.0.1:{router}"]
    started = []
    if server:
        started.append(peers({"middleware": "zenoh", "role": "server", "rmw": True,
                              "listen": "tcp/127.0.0.1:0", "connect": connect, "msg": [],
                              **server}))
        started[-1].wait_ready()
    beat = peers({"middleware": "zenoh", "role": "pub", "rmw": True, "repeat": True,
                  "listen": "tcp/127.0.0.1:0", "connect": connect, "topics": BEAT})
    return beat, *started


def records(trace: Path) -> list[dict]:
    return [json.loads(line) for line in trace.read_text().splitlines()]


def test_a_service_and_an_action_answer_into_knowledge(peers, tmp_path, zenoh_router):
    app = calls_app(tmp_path)
    _, server = robot(peers, zenoh_router, service="/double", action="/fibonacci")
    trace = tmp_path / "trace.mcap"
    run = rasm_run(app, f"zenoh://127.0.0.1:{zenoh_router}", tmp_path, "--duration", "6",
                   "--trace", str(trace))
    code, output = finish(run)
    found, channels = read_mcap(trace)
    # the MCAP trace has the request and the goal in their ROS 2 types, on their names
    assert channels["/double"][0][1].int32_value == 21
    assert channels["/fibonacci"][0][1].order == 6
    done = {r["effector_done"]: r for r in found if "effector_done" in r}
    assert set(done) == {"double", "fibonacci"}, output
    # the response and the result went into knowledge (and so the trace), feedback before it
    assert any(r.get("doubled") == 42 for r in found)
    sixth = next(i for i, r in enumerate(found) if r.get("sixth") == 5)
    third = next(i for i, r in enumerate(found) if r.get("third") == 1)
    assert third < sixth
    # the server got the request with the payload's value, and the goal's order
    assert any(e["event"] == "request" and e["int32_value"] == 21 for e in server.events)
    assert any(e["event"] == "goal" and e["order"] == 6 for e in server.events)
    executed = [r["explanation"] for r in found if r.get("executed")]
    assert any("service /double called by effector double" in e for e in executed)
    assert not [r for r in found if "effector_failed" in r]
    assert "effector double calls: 1 succeeded" in output
    assert "effector fibonacci calls: 1 succeeded" in output
    assert code == 0, output


def test_a_call_nobody_answers_fails_the_action_visibly_and_the_loop_goes_on(
    peers, tmp_path, zenoh_router
):
    app = calls_app(tmp_path)
    robot(peers, zenoh_router)  # a heartbeat, and nobody serving /double or /fibonacci
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(app, f"zenoh://127.0.0.1:{zenoh_router}", tmp_path, "--duration", "4",
                   "--trace", str(trace))
    code, output = finish(run)
    found = records(trace)
    failed = {r["effector_failed"]: r["explanation"] for r in found if "effector_failed" in r}
    assert set(failed) == {"double", "fibonacci"}, output
    assert "no server answers" in failed["double"]
    assert not any("doubled" in r for r in found)  # nothing about a failed call is known
    assert "effector double calls: 1 failed (last failure: service /double: no server" in output
    # the loop went on to the end
    assert any(r.get("stage") == "monitor" and r["time"] > 3 for r in found)
    assert code == 1, output  # doubled_right never judged


def test_a_goal_past_its_timeout_fails_and_is_cancelled_on_the_server(
    peers, tmp_path, zenoh_router
):
    def short(manifest):
        manifest["effectors"]["fibonacci"]["timeout"] = 1

    app = calls_app(tmp_path, short)
    _, server = robot(peers, zenoh_router, service="/double", action="/fibonacci", hang=True)
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(app, f"zenoh://127.0.0.1:{zenoh_router}", tmp_path, "--duration", "5",
                   "--trace", str(trace))
    code, output = finish(run)
    failed = [r for r in records(trace) if r.get("effector_failed") == "fibonacci"]
    assert failed and "no result within 1 s (goal cancelled)" in failed[0]["explanation"], output
    server.wait_for(lambda p: any(e["event"] == "cancelled" for e in p.events),
                    what="the cancel")
    assert "effector fibonacci calls: 1 failed" in output


def test_a_goal_is_cancelled_when_a_veto_property_closes(peers, tmp_path, zenoh_router):
    def veto(manifest):
        # the hanging server's feedback is [0, 1]: sequence[1] = 1 violates the veto property
        manifest["effectors"]["fibonacci"]["feedback"] = {"sequence[1]": "second"}
        manifest["trustworthiness"] = {"veto_properties": ["still_unknown"]}

    app = calls_app(tmp_path, veto)
    (app / "properties" / "calls.rv").write_text(
        "input doubled: int\ninput second: int = 0\n"
        "property still_unknown: always (second == 0)\n"
    )
    _, server = robot(peers, zenoh_router, service="/double", action="/fibonacci", hang=True)
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(app, f"zenoh://127.0.0.1:{zenoh_router}", tmp_path, "--duration", "5",
                   "--trace", str(trace))
    code, output = finish(run)
    goal = next(e for e in server.events if e["event"] == "goal")
    cancelled = server.wait_for(
        lambda p: [e for e in p.events if e["event"] == "cancelled"], what="the cancel")
    assert cancelled[0]["goal"] == goal["goal"]
    failed = [r for r in records(trace) if r.get("effector_failed") == "fibonacci"]
    assert failed, output
    assert "goal cancelled (veto property still_unknown violated" in failed[0]["explanation"]
    assert "effector fibonacci calls: 1 cancelled" in output


def test_a_goal_is_cancelled_when_the_fallback_engages(peers, tmp_path, zenoh_router):
    def fallback(manifest):
        manifest["effectors"]["stop"] = {"topic": "/stop", "type": "std_msgs/msg/Bool",
                                         "fields": {"data": "halt"}}
        manifest["fallback"] = {"actions": {"stop": {"halt": True}},
                                "when": ["managed_system_lost"], "dwell": 1}

    app = calls_app(tmp_path, fallback)
    beat, server = robot(peers, zenoh_router, service="/double", action="/fibonacci",
                         hang=True)
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(app, f"zenoh://127.0.0.1:{zenoh_router}", tmp_path, "--duration", "8",
                   "--trace", str(trace))
    server.wait_for(lambda p: any(e["event"] == "goal" for e in p.events), timeout=30,
                    what="the goal")
    beat.stop()  # the heartbeat goes silent: the robot is lost, the fallback engages
    cancelled = server.wait_for(
        lambda p: [e for e in p.events if e["event"] == "cancelled"], what="the cancel")
    code, output = finish(run)
    found = records(trace)
    engaged = next(i for i, r in enumerate(found) if r.get("fallback") == "engaged")
    failed = next(i for i, r in enumerate(found) if r.get("effector_failed") == "fibonacci")
    assert engaged < failed, output
    assert "goal cancelled (the fallback engaged)" in found[failed]["explanation"]
    assert cancelled[0]["goal"] == next(e for e in server.events if e["event"] == "goal")["goal"]


def test_services_and_actions_need_a_ros_transport(tmp_path, capsys):
    from rasm.cli import main

    app = calls_app(tmp_path)
    assert main(["run", str(app), "--transport", "local", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert ("effector double calls service /double: services and actions are ROS 2's; run "
            "the app over zenoh:// or dds://") in err
    assert "Traceback" not in err


def test_over_dds_a_service_and_an_action_answer_into_knowledge(peers, tmp_path, dds_domain):
    app = calls_app(tmp_path)
    server = peers({"middleware": "dds", "role": "server", "domain": dds_domain,
                    "interfaces": str(TEST_INTERFACES), "service": "/double",
                    "action": "/fibonacci"})
    server.wait_ready()
    peers({"middleware": "dds", "role": "pub", "domain": dds_domain, "repeat": True,
           "topics": BEAT})
    trace = tmp_path / "trace.jsonl"
    run = rasm_run(app, f"dds://?domain={dds_domain}", tmp_path, "--duration", "6",
                   "--trace", str(trace))
    code, output = finish(run)
    found = records(trace)
    assert {r["effector_done"] for r in found if "effector_done" in r} == {
        "double", "fibonacci"}, output
    assert any(r.get("doubled") == 42 for r in found)
    assert any(r.get("sixth") == 5 for r in found) and any(r.get("third") == 1 for r in found)
    assert any(e["event"] == "goal" and e["order"] == 6 for e in server.events)
    assert code == 0, output


def test_the_calls_are_made_before_the_checker_and_hold_no_block(tmp_path, zenoh_router):
    # the assembly: the calls are made before the Trustworthiness Checker (its action sender
    # starts them) with the veto properties, and read a veto from the verdict alone, so they
    # hold neither the Trustworthiness Manager nor any other block; a veto's verdict reaches
    # them before the fallback switch's, a record the fallback engaged on reaches them too
    from rasm import Platform, RunOptions
    from rasm.platform.block import Block

    def veto_and_fallback(manifest):
        manifest["trustworthiness"] = {"veto_properties": ["progress"]}
        manifest["effectors"]["stop"] = {"topic": "/stop", "type": "std_msgs/msg/Bool",
                                         "fields": {"data": "halt"}}
        manifest["fallback"] = {"actions": {"stop": {"halt": True}},
                                "when": ["managed_system_lost"], "dwell": 1}

    platform = Platform(calls_app(tmp_path, veto_and_fallback), RunOptions(
        transport=f"zenoh://127.0.0.1:{zenoh_router}", knowledge="memory",
        state_dir=tmp_path / "state",
    ))
    platform.build()
    try:
        side = platform.managing
        calls = side.call_effectors
        assert calls is not None
        assert tuple(calls.veto_properties) == side.trustworthiness_manager.veto_properties
        assert "progress" in calls.veto_properties
        assert not any(isinstance(value, Block) for value in vars(calls).values())
        verdicts = platform.on_verdict
        assert (verdicts.index(calls.observe_verdict)
                < verdicts.index(side.fallback_switch.watch_verdict))
        assert calls.observe_record in platform.on_record
    finally:
        platform.stop()
