"""HMAC-signed payloads, the update receiver over a real broker, and the effector gate."""

from __future__ import annotations

import json
import random

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rasm.comm import BoundSigner, Message, SignedEffector, UpdateReceiver, sign, verify
from rasm.comm.signing import SIGNATURE, UPDATE_TOPICS, ReplayGuard, canonical
from rasm.errors import CommError
from rasm.rules import RuleSet, parse_rules
from tests.comm.strategies import JSON_VALUES
from tests.comm.support import Inbox

KEY = b"checker-key-0123456789abcdef"

payloads = st.dictionaries(
    st.text(max_size=10).filter(lambda k: k != SIGNATURE), JSON_VALUES, min_size=1, max_size=6
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


@pytest.mark.slow
@given(payloads, keys, st.randoms(use_true_random=False))
def test_a_signed_payload_verifies_whatever_its_key_order(payload, key, rng):
    signed = sign(payload, key)
    assert verify(signed, key)
    assert verify(_shuffled(signed, rng), key)
    # and after a trip through JSON, as over the bus
    assert verify(json.loads(json.dumps(signed)), key)


@pytest.mark.slow
@given(payloads, keys, keys)
def test_a_wrong_key_fails(payload, key, other):
    assume(key != other)
    assert not verify(sign(payload, key), other)


@given(payloads, keys, st.data())
def test_any_change_of_any_field_fails(payload, key, data):
    signed = sign(payload, key)
    field = data.draw(st.sampled_from(sorted(payload)))
    new = data.draw(JSON_VALUES)
    assume(canonical({field: new}) != canonical({field: payload[field]}))
    changed = dict(signed)
    changed[field] = new
    assert not verify(changed, key)


@given(payloads, keys, st.text(min_size=1, max_size=10), JSON_VALUES)
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


def _bound(signer: BoundSigner, receiver, kind: str, payload: dict, **bind) -> dict:
    """``payload`` signed by ``signer`` for ``receiver`` on the topic of ``kind`` updates."""
    bind = {"topic": UPDATE_TOPICS[kind][0], "epochs": [receiver.epoch], **bind}
    return signer.sign(payload, **bind)


def test_only_signed_bound_consistent_rule_sets_are_applied_over_mqtt(mqtt):
    ruleset = RuleSet(parse_rules(CONSISTENT, source="initial.yaml"))
    node, operator = mqtt(), mqtt()
    results = Inbox()
    operator.subscribe("rasm/update/result", results, qos=1)
    receiver = UpdateReceiver(node, KEY, rules=_rules_applier(ruleset)).start()
    signer = BoundSigner(KEY)

    def send(payload: dict) -> dict:
        operator.publish("rasm/update/rules", payload, qos=1)
        return results.get().payload

    unsigned = send({"rules": OTHER_CONSISTENT})
    forged = send(
        BoundSigner(b"someone else's key").sign(
            {"rules": OTHER_CONSISTENT}, topic="rasm/update/rules", epochs=[receiver.epoch]
        )
    )
    tampered = _bound(signer, receiver, "rules", {"rules": CONSISTENT})
    tampered["rules"] = OTHER_CONSISTENT
    tampered = send(tampered)
    unbound = send(sign({"rules": OTHER_CONSISTENT}, KEY))
    elsewhere = send(_bound(signer, receiver, "rules", {"rules": OTHER_CONSISTENT}, epochs=["x"]))
    wrong_topic = send(
        _bound(signer, receiver, "rules", {"rules": OTHER_CONSISTENT}, topic="rasm/update/x")
    )
    inconsistent = send(_bound(signer, receiver, "rules", {"rules": INCONSISTENT}))
    refusals = (unsigned, forged, tampered, unbound, elsewhere, wrong_topic, inconsistent)
    assert [r["accepted"] for r in refusals] == [False] * 7
    assert unsigned["reason"] == "unsigned"
    assert forged["reason"] == tampered["reason"] == "bad signature"
    assert "not bound to a receiver's incarnation" in unbound["reason"]
    assert "signed for another incarnation" in elsewhere["reason"]
    assert wrong_topic["reason"] == (
        "signed for topic 'rasm/update/x', received on 'rasm/update/rules'"
    )
    assert inconsistent["reason"].startswith("applier refused: rules kept")
    assert "inconsistent" in inconsistent["reason"]
    # every answer tells the sender the epoch to bind to
    assert {r["epoch"] for r in refusals} == {receiver.epoch}
    # the rules in force are still the initial ones
    assert ruleset.evaluate({"velocity": 0.15}, {"mode": "dock"}).accepted is False

    good = _bound(signer, receiver, "rules", {"rules": OTHER_CONSISTENT})
    assert send(good)["accepted"] is True
    assert ruleset.evaluate({"velocity": 0.15}, {"mode": "dock"}).accepted is True
    replayed = send(good)
    assert replayed["accepted"] is False
    assert (
        replayed["reason"] == f"replayed or stale: sequence {signer.seq} of run {signer.run} "
        f"after {signer.seq}"
    )
    kinds = [(o.kind, o.accepted) for o in receiver.outcomes]
    assert kinds == [("rules", False)] * 7 + [("rules", True), ("rules", False)]
    assert receiver.refused == 8
    receiver.stop()


def test_an_update_replayed_into_a_restarted_receiver_is_refused(mqtt):
    """The update a receiver accepted is refused by its next incarnation; a restarted sender
    (a new run, its sequence back at 1) is heard by both."""
    applied: list[str] = []
    node, operator = mqtt(), mqtt()
    results = Inbox()
    operator.subscribe("rasm/update/result", results, qos=1)

    def apply(text: str) -> tuple[bool, str]:
        applied.append(text)
        return True, "monitors replaced"

    def send(payload: dict) -> dict:
        operator.publish("rasm/update/properties", payload, qos=1)
        return results.get().payload

    first = UpdateReceiver(node, KEY, properties=apply).start()
    sender = BoundSigner(KEY)
    update = _bound(sender, first, "properties", {"spec": "property p: always x"})
    assert send(update)["accepted"]
    assert send(update)["reason"].startswith("replayed or stale: sequence 1")
    restarted_sender = BoundSigner(KEY)
    assert send(_bound(restarted_sender, first, "properties", {"spec": "property p: always y"}))[
        "accepted"
    ]
    first.stop()

    second = UpdateReceiver(node, KEY, properties=apply).start()  # the process restarted
    assert second.epoch != first.epoch
    refused = send(update)
    assert refused["accepted"] is False and "another incarnation" in refused["reason"]
    assert refused["epoch"] == second.epoch
    assert send(_bound(restarted_sender, second, "properties", {"spec": "property p: always z"}))[
        "accepted"
    ]
    assert applied == ["property p: always x", "property p: always y", "property p: always z"]


def test_an_applier_that_raises_is_a_refusal(caplog):
    def broken(text: str) -> tuple[bool, str]:
        raise RuntimeError("disk full")

    receiver = UpdateReceiver(object(), KEY, rules=broken, reply=False)  # type: ignore[arg-type]
    update = _bound(BoundSigner(KEY), receiver, "rules", {"rules": "x"})
    outcome = receiver.receive("rules", Message("rasm/update/rules", update))
    assert outcome.accepted is False
    assert outcome.reason == "applier failed: RuntimeError: disk full"
    none = receiver.receive("properties", Message("t", sign({"spec": "x"}, KEY)))
    assert none.reason == "no applier for properties updates"


# ----------------------------------------------------------------------- actions


def test_the_effector_gate_passes_only_checker_signed_bound_new_actions(mqtt):
    executed: list[dict] = []
    gate = SignedEffector(KEY, executed.append, topic="robot/cmd")
    effector_side, checker = mqtt(), mqtt()
    done = Inbox()
    effector_side.subscribe(
        "robot/cmd",
        lambda m: done((gate.handle(m.payload), m)),
        qos=1,  # type: ignore[arg-type]
    )
    signer = BoundSigner(KEY)
    action = {"plan": "p7", "velocity": 0.1}

    def bound(**bind) -> dict:
        return signer.sign(action, **{"topic": "robot/cmd", "epochs": [gate.epoch], **bind})

    good = bound()
    for payload in (
        action,  # unsigned
        BoundSigner(b"planner key").sign(action, topic="robot/cmd", epochs=[gate.epoch]),
        sign(action, KEY),  # signed by the checker, but not bound
        bound(epochs=["an-earlier-incarnation"]),
        bound(topic="robot/other"),
        good,
        good,  # the same action again: a replay
        bound(),  # a new one
    ):
        checker.publish("robot/cmd", payload, qos=1)
    outcomes = [ok for ok, _ in done.take(8)]
    assert outcomes == [False, False, False, False, False, True, False, True]
    # the effector sees the action without its signature and binding
    assert executed == [action, action]
    assert (gate.accepted, gate.refused) == (2, 6)
    assert gate.last_refusal == f"replayed or stale: sequence 1 of run {signer.run} after 1"


# ----------------------------------------------------------------------- the acceptance rule

EPOCHS = ("e-now", "e-before", "e-other")
RUNS = ("r1", "r2", "r3")
messages = st.lists(
    st.tuples(
        st.lists(st.sampled_from(EPOCHS), max_size=3),
        st.sampled_from(RUNS),
        st.integers(min_value=-2, max_value=12),
        st.sampled_from(("t", "u")),
    ),
    max_size=40,
)


@given(messages)
def test_the_guard_admits_exactly_the_bound_newer_messages(sequence):
    """For any sequence of (epochs, run, seq, topic): admitted iff bound to this epoch and
    topic, seq a positive integer, and above every seq admitted from that run before."""
    guard = ReplayGuard("e-now")
    highest: dict[str, int] = {}
    admitted: list[tuple[str, int]] = []
    for epochs, run, seq, topic in sequence:
        binding = {"epochs": epochs, "run": run, "seq": seq, "topic": topic}
        expected = "e-now" in epochs and topic == "t" and seq >= 1 and seq > highest.get(run, 0)
        assert (guard.admit(binding, "t") is None) is expected, (binding, highest)
        if expected:
            highest[run] = seq
            admitted.append((run, seq))
    # never the same (run, seq) twice, and within a run in increasing order
    assert len(set(admitted)) == len(admitted)
    for run in RUNS:
        seqs = [seq for r, seq in admitted if r == run]
        assert seqs == sorted(seqs)


@given(st.lists(st.integers(min_value=0, max_value=9), max_size=30), st.randoms())
def test_signed_actions_replayed_in_any_order_apply_at_most_once(picks, rng):
    """A capture of every action two sender runs sent, replayed in any order and any number of
    times: each applies at most once, and a restarted effector (a new gate) applies none."""
    runs = [BoundSigner(KEY), BoundSigner(KEY)]
    applied: list[dict] = []
    gate = SignedEffector(KEY, applied.append, topic="robot/cmd")
    sent = [runs[i % 2].sign({"n": i}, topic="robot/cmd", epochs=[gate.epoch]) for i in range(10)]
    for i in picks:
        gate.handle(sent[i])
    capture = sent + [sent[i] for i in picks]
    rng.shuffle(capture)
    for payload in capture:
        gate.handle(payload)
    numbers = [action["n"] for action in applied]
    assert len(set(numbers)) == len(numbers)
    for parity in (0, 1):  # each run's actions applied in the order it sent them
        mine = [n for n in numbers if n % 2 == parity]
        assert mine == sorted(mine)
    restarted = SignedEffector(KEY, applied.append, topic="robot/cmd")
    assert not any(restarted.handle(payload) for payload in capture)
    assert restarted.refused == len(capture)


def test_a_signer_refuses_to_bind_to_nobody_and_bad_run_ids():
    signer = BoundSigner(KEY, run="r1")
    with pytest.raises(CommError, match="no receiver has announced its epoch"):
        signer.sign({"a": 1}, topic="t", epochs=[])
    assert signer.seq == 0  # nothing was signed
    with pytest.raises(CommError, match="run id"):
        BoundSigner(KEY, run="")
    guard = ReplayGuard("e")
    for binding, why in (
        ({"epochs": "e", "run": "r", "seq": 1, "topic": "t"}, "another incarnation"),
        ({"epochs": ["e"], "run": 7, "seq": 1, "topic": "t"}, "run id is not valid"),
        ({"epochs": ["e"], "run": "r", "seq": True, "topic": "t"}, "not a positive integer"),
        ({"epochs": ["e"], "run": "r", "seq": 1.0, "topic": "t"}, "not a positive integer"),
        ({"epochs": ["e"], "run": "r", "seq": 0, "topic": "t"}, "not a positive integer"),
    ):
        assert why in guard.admit(binding, "t")


def test_a_flood_of_refused_actions_is_logged_once_then_counted(caplog):
    applied: list[dict] = []
    gate = SignedEffector(KEY, applied.append, topic="robot/heater")
    signer = BoundSigner(KEY)
    action = signer.sign({"mode": "boost"}, topic="robot/heater", epochs=[gate.epoch])
    assert gate.handle(action) is True
    with caplog.at_level("WARNING", logger="rasm.comm"):
        for _ in range(50):  # an attacker replaying a captured action, and unsigned junk
            gate.handle(action)
            gate.handle({"mode": "boost"})
    refusals = [r.getMessage() for r in caplog.records if "refused by the effector gate" in r.msg]
    assert len(refusals) == 2  # the first replay and the first unsigned one, in full
    assert any("replayed or stale: sequence 1" in text for text in refusals)
    assert gate.refused == 100 and applied == [{"mode": "boost"}]
    assert gate.logs.totals == {
        "action refused by the effector gate: replayed or stale": 50,
        "action refused by the effector gate: unsigned": 50,
    }
