"""Service calls and action goals over Zenoh against a server written with eclipse-zenoh and
rosbags alone (tests/ros2/peer.py, role "server"), through a router configured as rmw_zenohd."""

from __future__ import annotations

import os
import threading

import pytest

from rasm.ros2 import TypeStore
from rasm.ros2.calls import ActionGoal, CallFailed, ZenohCalls
from rasm.ros2.zenoh import ZenohTransport
from tests.ros2.conftest import wait_until
from tests.ros2.test_interfaces import TEST_INTERFACES

pytestmark = pytest.mark.skipif(not TEST_INTERFACES.is_dir(),
                                reason="Debian's ros2-test-interface-files is not installed")


def _store() -> TypeStore:
    store = TypeStore()
    store.add_interface_dir(TEST_INTERFACES, "test_msgs")
    return store


def _server(peers, router, **config):
    server = peers({"middleware": "zenoh", "role": "server", "listen": "tcp/127.0.0.1:0",
                    "connect": [f"tcp/127.0.0.1:{router}"], "rmw": True, "msg": [], **config})
    server.wait_ready()
    return server


def _calls(transports, router):
    transport = transports(ZenohTransport(f"zenoh://127.0.0.1:{router}", store=_store()))
    transport.connect()
    return ZenohCalls(transport)


def test_a_service_call_gets_the_servers_response(peers, transports, zenoh_router):
    server = _server(peers, zenoh_router, service="/basic")
    calls = _calls(transports, zenoh_router)
    response = wait_until(lambda: _try(lambda: calls.call(
        "/basic", "test_msgs/srv/BasicTypes", {"int32_value": 21}, timeout=2.0)),
        what="the service's response")
    assert response["int32_value"] == 42
    # the request went out with the .msg defaults and on rmw_zenoh's key
    request = next(e for e in server.events if e["event"] == "request")
    assert request["key"].startswith(
        "0/basic/test_msgs::srv::dds_::BasicTypes_/RIHS01_"
    )
    assert request["key"].endswith(
        calls.transport.store.type_hash("test_msgs/srv/BasicTypes")
    )


def test_a_service_nobody_serves_fails_loudly(transports, zenoh_router):
    calls = _calls(transports, zenoh_router)
    with pytest.raises(CallFailed, match="no server answers"):
        calls.call("/nobody", "test_msgs/srv/BasicTypes", {}, timeout=1.0)


def test_an_action_goal_reports_feedback_and_its_result(peers, transports, zenoh_router):
    server = _server(peers, zenoh_router, action="/fibonacci")
    calls = _calls(transports, zenoh_router)
    feedback = []

    def pursue():
        return calls.pursue("/fibonacci", "test_msgs/action/Fibonacci", {"order": 6}, 10.0,
                            feedback.append, ActionGoal(os.urandom(16)))

    result = wait_until(lambda: _try(pursue), what="the goal's result")
    assert result == {"sequence": [0, 1, 1, 2, 3, 5]}
    assert feedback and feedback[-1] == {"sequence": [0, 1, 1, 2, 3, 5]}
    assert any(e["event"] == "goal" and e["order"] == 6 for e in server.events)


def _cancel_a_running_goal(server, calls):
    """Pursue a goal the server never ends, cancel it once its feedback comes: the pursuit's
    failure, the feedback, the goal and the server's cancel events."""
    goal = ActionGoal(os.urandom(16))
    failure = []
    feedback = []

    def pursue():
        try:
            calls.pursue("/fibonacci", "test_msgs/action/Fibonacci", {"order": 3}, 30.0,
                         feedback.append, goal)
        except CallFailed as exc:
            failure.append(str(exc))

    worker = threading.Thread(target=pursue)
    worker.start()
    server.wait_for(lambda p: any(e["event"] == "goal" for e in p.events), what="the goal")
    # feedback comes while the goal runs, not only with its result
    wait_until(lambda: feedback, what="feedback of the running goal")
    goal.cancel("fallback engaged")
    worker.join(10)
    cancelled = server.wait_for(
        lambda p: [e for e in p.events if e["event"] == "cancelled"], what="the cancel")
    return failure, feedback, goal, cancelled


def test_a_cancelled_goal_is_seen_cancelled_by_the_server(peers, transports, zenoh_router):
    server = _server(peers, zenoh_router, action="/fibonacci", hang=True)
    failure, feedback, goal, cancelled = _cancel_a_running_goal(
        server, _calls(transports, zenoh_router))
    assert feedback[0] == {"sequence": [0, 1]}
    assert failure and "goal cancelled (fallback engaged)" in failure[0]
    assert cancelled[0]["goal"] == goal.goal_id.hex()
    assert "test_msgs/action" not in cancelled[0]["key"]
    assert "/_action/cancel_goal/action_msgs::srv::dds_::CancelGoal_/RIHS01_" in (
        cancelled[0]["key"]
    )


@pytest.mark.slow
def test_a_goal_past_its_timeout_fails_and_is_cancelled(peers, transports, zenoh_router):
    server = _server(peers, zenoh_router, action="/fibonacci", hang=True)
    calls = _calls(transports, zenoh_router)
    failure = []

    def pursue():
        try:
            return calls.pursue("/fibonacci", "test_msgs/action/Fibonacci", {"order": 3}, 1.0,
                                lambda _: None, ActionGoal(os.urandom(16)))
        except CallFailed as exc:
            if "no server answers" in str(exc):
                return None
            failure.append(str(exc))
            return True

    wait_until(pursue, what="the goal to fail")
    assert failure == ["action /fibonacci: no result within 1 s (goal cancelled)"]
    server.wait_for(lambda p: any(e["event"] == "cancelled" for e in p.events),
                    what="the cancel")


def _try(call):
    """The call's answer, or None while the server is not yet discovered."""
    try:
        return call()
    except CallFailed as exc:
        if "no server answers" in str(exc):
            return None
        raise


# -- over DDS: the same calls against the server written with cyclonedds and rosbags ----------
def _dds_server(peers, domain, **config):
    server = peers({"middleware": "dds", "role": "server", "domain": domain,
                    "interfaces": str(TEST_INTERFACES), **config})
    server.wait_ready()
    return server


def _dds_calls(transports, domain):
    from rasm.ros2.calls import DdsCalls
    from rasm.ros2.dds import DdsTransport

    transport = transports(DdsTransport(f"dds://?domain={domain}", store=_store()))
    transport.connect()
    return DdsCalls(transport)


def test_a_dds_service_call_gets_the_servers_response(peers, transports, dds_domain):
    server = _dds_server(peers, dds_domain, service="/basic")
    calls = _dds_calls(transports, dds_domain)
    response = calls.call("/basic", "test_msgs/srv/BasicTypes",
                          {"int32_value": 21, "string_value": "hi"}, timeout=10.0)
    assert response["int32_value"] == 42 and response["string_value"] == "hi"
    assert [e["int32_value"] for e in server.events if e["event"] == "request"] == [21]
    # two more, one after the other: each answer is its own request's
    assert calls.call("/basic", "test_msgs/srv/BasicTypes", {"int32_value": 1},
                      timeout=5.0)["int32_value"] == 2
    assert calls.call("/basic", "test_msgs/srv/BasicTypes", {"int32_value": 5},
                      timeout=5.0)["int32_value"] == 10


def test_a_dds_service_nobody_serves_fails_loudly(transports, dds_domain):
    calls = _dds_calls(transports, dds_domain)
    with pytest.raises(CallFailed, match="no server answers"):
        calls.call("/nobody", "test_msgs/srv/BasicTypes", {}, timeout=1.0)


def test_a_dds_action_goal_reports_feedback_and_its_result(peers, transports, dds_domain):
    server = _dds_server(peers, dds_domain, action="/fibonacci")
    calls = _dds_calls(transports, dds_domain)
    feedback = []
    result = calls.pursue("/fibonacci", "test_msgs/action/Fibonacci", {"order": 6}, 10.0,
                          feedback.append, ActionGoal(os.urandom(16)))
    assert result == {"sequence": [0, 1, 1, 2, 3, 5]}
    assert feedback and feedback[-1] == {"sequence": [0, 1, 1, 2, 3, 5]}
    assert any(e["event"] == "goal" and e["order"] == 6 for e in server.events)


def test_a_cancelled_dds_goal_is_seen_cancelled_by_the_server(peers, transports, dds_domain):
    server = _dds_server(peers, dds_domain, action="/fibonacci", hang=True)
    failure, _, goal, cancelled = _cancel_a_running_goal(
        server, _dds_calls(transports, dds_domain))
    assert failure == ["action /fibonacci: goal cancelled (fallback engaged)"]
    assert cancelled[0]["goal"] == goal.goal_id.hex()
