"""Actions out: what goes on an effector's topic for an action, and what a replay does instead."""

from __future__ import annotations

import pytest

from rasm.comm import open_transport
from rasm.platform.actions_out import ActionSender
from rasm.platform.components import Action
from rasm.platform.manifest import load_manifest
from rasm.platform.messages import ActionMismatch
from rasm.statechart import SimulatedClock

from .conftest import HOTBOX, ROOT

GUARD = ROOT / "tests" / "ros2" / "data" / "guard"


def sender(manifest, *, replaying=False, seal=lambda topic, payload: payload):
    """An ActionSender on a real local bus: (sender, messages delivered, trace records)."""
    transport = open_transport("local")
    transport.connect()
    delivered, records = [], []
    for effector in manifest.effectors.values():
        transport.subscribe(effector.topic, lambda message: delivered.append(message))
    clock = SimulatedClock()
    clock.time = 12.5
    out = ActionSender(
        manifest,
        publish=transport.publish,
        seal=seal,
        emit=lambda time, record: records.append((time, record)),
        clock=clock,
        replaying=replaying,
    )
    return out, delivered, records


def test_an_untyped_action_goes_out_sealed_with_its_plan_and_kind():
    manifest = load_manifest(HOTBOX)
    out, delivered, records = sender(
        manifest, seal=lambda topic, payload: {**payload, "sealed_for": topic}
    )
    heater = manifest.effectors["heater"]
    assert out.send(heater, Action("heater", {"mode": "boost"}, "p3")) is None
    assert [(m.topic, m.payload) for m in delivered] == [
        (
            "hotbox/heater",
            {"mode": "boost", "plan": "p3", "kind": "adaptation", "sealed_for": "hotbox/heater"},
        )
    ]
    assert records == []


def test_a_replay_sends_nothing_and_traces_the_action_as_it_would_have_gone_out():
    manifest = load_manifest(HOTBOX)
    out, delivered, records = sender(manifest, replaying=True)
    heater = manifest.effectors["heater"]
    why = out.send(heater, Action("heater", {"mode": "normal"}, "p1", "diagnosis"))
    assert why == "recorded in the trace, not sent (replay): heater on hotbox/heater"
    assert delivered == []
    payload = {"mode": "normal", "plan": "p1", "kind": "diagnosis"}
    action = {"effector": "heater", "topic": "hotbox/heater", "payload": payload}
    assert records == [(12.5, {"recorded_action": action, "plan": "p1"})]


def test_a_typed_action_is_its_effectors_message_and_is_not_sealed():
    manifest = load_manifest(GUARD)
    out, delivered, records = sender(manifest, seal=None)  # sealing it would fail the test
    state = manifest.effectors["state"]
    fields = {"level": 2, "reason": "obstacle ahead"}
    assert out.send(state, Action("state", fields, "p2")) is None
    assert [(m.topic, m.payload) for m in delivered] == [("/guard_state", fields)]
    with pytest.raises(ActionMismatch):  # a payload the message has no field for fails closed
        out.send(state, Action("state", {**fields, "speed": 1.0}, "p4"))
