"""HMAC-signed payloads, the update receiver over a real broker, and the effector gate."""

from __future__ import annotations

import json
import random

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rasm.comm import Message, SignedEffector, UpdateReceiver, sign, verify
from rasm.comm.signing import SIGNATURE, canonical
from rasm.errors import CommError
from rasm.rules import RuleSet
from rasm.rules.loader import parse_rules
from tests.distribution.conftest import Inbox

KEY = b"checker-key-0123456789abcdef"

scalars = (
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**63), max_value=2**63)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=20)
)
json_values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)
payloads = st.dictionaries(
    st.text(max_size=10).filter(lambda k: k != SIGNATURE), json_values, min_size=1, max_size=6
)
keys = st.binary(min_size=1, max_size=64)


def _shuffled(value, rng: random.Random):
    """The same JSON value with every dict's keys in another order."""
    if isinstance(value, dict):
        items = list(value.items())
        rng.shuffle(items)
        return {k: _shuffled(v, rng) for k, v in items}
    if isinstance(value, list):
        return [_shuffled(v, rng) for v in value]
    return value


@given(payloads, keys, st.randoms(use_true_random=False))
def test_a_signed_payload_verifies_whatever_its_key_order(payload, key, rng):
    signed = sign(payload, key)
    assert verify(signed, key)
    assert verify(_shuffled(signed, rng), key)
    # and after a trip through JSON, as over the bus
    assert verify(json.loads(json.dumps(signed)), key)


@given(payloads, keys, keys)
def test_a_wrong_key_fails(payload, key, other):
    assume(key != other)
    assert not verify(sign(payload, key), other)


@given(payloads, keys, st.data())
def test_any_change_of_any_field_fails(payload, key, data):
    signed = sign(payload, key)
    field = data.draw(st.sampled_from(sorted(payload)))
    new = data.draw(json_values)
    assume(canonical({field: new}) != canonical({field: payload[field]}))
    changed = dict(signed)
    changed[field] = new
    assert not verify(changed, key)


@given(payloads, keys, st.text(min_size=1, max_size=10), json_values)
def test_an_added_or_removed_field_fails(payload, key, extra, value):
    signed = sign(payload, key)
    assume(extra not in signed)
    assert not verify({**signed, extra: value}, key)
    removed = dict(signed)
    del removed[sorted(payload)[0]]
    assert not verify(removed, key)


@given(payloads, keys)
def test_a_changed_nested_value_fails(payload, key):
    nested = {**payload, "plan": {"velocity": 0.1, "steps": [1, 2, 3]}}
    signed = sign(nested, key)
    tampered = json.loads(json.dumps(signed))
    tampered["plan"]["steps"][2] = 4
    assert not verify(tampered, key)
    tampered["plan"]["steps"][2] = 3.0  # 3 and 3.0 are different JSON
    assert not verify(tampered, key)


def test_bad_payloads_never_verify_and_bad_keys_are_refused():
    assert not verify({"spec": "x"}, KEY)  # unsigned
    assert not verify({"spec": "x", SIGNATURE: 42}, KEY)
    assert not verify({"spec": "x", SIGNATURE: "é" * 64}, KEY)
    assert not verify(["not", "a", "dict"], KEY)
    assert not verify({"x": float("nan"), SIGNATURE: "00"}, KEY)
    with pytest.raises(CommError, match="non-empty bytes"):
        sign({"a": 1}, b"")
    with pytest.raises(CommError, match="non-empty bytes"):
        verify({"a": 1}, "text key")  # type: ignore[arg-type]
    with pytest.raises(CommError, match="cannot sign"):
        sign({"a": float("inf")}, KEY)
    signed = sign({"a": 1, SIGNATURE: "old"}, KEY)  # re-signing replaces the old signature
    assert verify(signed, KEY)


# ----------------------------------------------------------------------- updates over a broker

CONSISTENT = """
variables:
  velocity: {type: real, min: 0, max: 1.0}
  mode: {type: enum, values: [navigate, dock]}
rules:
  - name: slow_docking
    when: mode == "dock"
    require: velocity <= 0.1
"""

OTHER_CONSISTENT = CONSISTENT.replace("velocity <= 0.1", "velocity <= 0.2")

INCONSISTENT = (
    CONSISTENT
    + """  - name: fast_docking
    when: mode == "dock"
    require: velocity >= 0.5
"""
)


def _rules_applier(ruleset: RuleSet):
    def apply(text: str) -> tuple[bool, str]:
        result = ruleset.swap_text(text, source="<update>")
        return result.accepted, result.reason

    return apply


def test_only_signed_consistent_rule_sets_are_applied_over_mqtt(mqtt):
    ruleset = RuleSet(parse_rules(CONSISTENT, source="initial.yaml"))
    node, operator = mqtt(), mqtt()
    results = Inbox()
    operator.subscribe("rasm/update/result", results, qos=1)
    receiver = UpdateReceiver(node, KEY, rules=_rules_applier(ruleset)).start()

    def send(payload: dict) -> dict:
        operator.publish("rasm/update/rules", payload, qos=1)
        return results.get().payload

    unsigned = send({"rules": OTHER_CONSISTENT})
    forged = send(sign({"rules": OTHER_CONSISTENT}, b"someone else's key"))
    tampered = sign({"rules": CONSISTENT}, KEY)
    tampered["rules"] = OTHER_CONSISTENT
    tampered = send(tampered)
    inconsistent = send(sign({"rules": INCONSISTENT}, KEY))
    assert [r["accepted"] for r in (unsigned, forged, tampered, inconsistent)] == [False] * 4
    assert unsigned["reason"] == "unsigned"
    assert forged["reason"] == tampered["reason"] == "bad signature"
    assert inconsistent["reason"].startswith("applier refused: rules kept")
    assert "inconsistent" in inconsistent["reason"]
    # the rules in force are still the initial ones
    assert ruleset.evaluate({"velocity": 0.15}, {"mode": "dock"}).accepted is False

    accepted = send(sign({"rules": OTHER_CONSISTENT}, KEY))
    assert accepted["accepted"] is True
    assert ruleset.evaluate({"velocity": 0.15}, {"mode": "dock"}).accepted is True
    kinds = [(o.kind, o.accepted) for o in receiver.outcomes]
    assert kinds == [("rules", False)] * 4 + [("rules", True)]
    receiver.stop()


def test_property_updates_and_versions(mqtt):
    applied: list[str] = []
    node, operator = mqtt(), mqtt()
    results = Inbox()
    operator.subscribe("rasm/update/result", results, qos=1)
    UpdateReceiver(
        node, KEY, properties=lambda text: (applied.append(text) or True, "monitors replaced")
    ).start()

    def send(payload: dict) -> dict:
        operator.publish("rasm/update/properties", payload, qos=1)
        return results.get().payload

    assert send(sign({"spec": "property p: always x", "version": 2}, KEY))["accepted"]
    replay = send(sign({"spec": "property p: always y", "version": 2}, KEY))
    assert replay == {
        "kind": "properties",
        "accepted": False,
        "reason": "replayed or stale: version 2 after 2",
        "update": replay["update"],
    }
    assert not send(sign({"spec": 42}, KEY))["accepted"]
    assert send(sign({"spec": "property p: always z", "version": 3}, KEY))["accepted"]
    assert applied == ["property p: always x", "property p: always z"]


def test_an_applier_that_raises_is_a_refusal(caplog):
    def broken(text: str) -> tuple[bool, str]:
        raise RuntimeError("disk full")

    receiver = UpdateReceiver(object(), KEY, rules=broken, reply=False)  # type: ignore[arg-type]
    outcome = receiver.receive("rules", Message("rasm/update/rules", sign({"rules": "x"}, KEY)))
    assert outcome.accepted is False
    assert outcome.reason == "applier failed: RuntimeError: disk full"
    none = receiver.receive("properties", Message("t", sign({"spec": "x"}, KEY)))
    assert none.reason == "no applier for properties updates"


# ----------------------------------------------------------------------- actions


def test_the_effector_gate_passes_only_checker_signed_new_actions(mqtt):
    executed: list[dict] = []
    gate = SignedEffector(KEY, executed.append)
    effector_side, checker = mqtt(), mqtt()
    done = Inbox()
    effector_side.subscribe(
        "robot/cmd",
        lambda m: done((gate.handle(m.payload), m)),
        qos=1,  # type: ignore[arg-type]
    )
    action = {"plan": "p7", "velocity": 0.1, "seq": 1}
    for payload in (
        action,  # unsigned
        sign(action, b"planner key"),  # not the checker's key
        sign(action, KEY),  # good
        sign(action, KEY),  # the same signed action again: a replay
        sign({**action, "seq": 2}, KEY),  # a new one
    ):
        checker.publish("robot/cmd", payload, qos=1)
    outcomes = [ok for ok, _ in done.take(5)]
    assert outcomes == [False, False, True, False, True]
    assert executed == [action, {**action, "seq": 2}]
    assert (gate.accepted, gate.refused, gate.last_refusal) == (2, 3, "replayed")
