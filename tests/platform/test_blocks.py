"""Telegraf's data checks, the logging sinks, and blocks refusing work outside their mode."""

from __future__ import annotations

import json
import math
from collections import Counter

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm import Platform
from rasm.platform.components import Action
from rasm.platform.manifest import Effector, Probe, Signal
from rasm.platform.telegraf import Telegraf, _check_value
from rasm.platform.trustworthiness_checker import TrustworthinessChecker

PROBE = Probe(
    "box/sensors",
    {
        "temperature": Signal("temperature", "float", -40.0, 150.0),
        "lid_open": Signal("lid_open", "bool"),
        "count": Signal("count", "int", 0, 10),
        "mode": Signal("mode", "str"),
    },
)


def started_telegraf():
    stored = []
    tg = Telegraf([PROBE], lambda values, time: stored.append(dict(values)))
    tg.send("configure")
    assert tg.mode == "initialized"
    return tg, stored


def valid(signal, value):
    if signal.type == "float":
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        return ok and math.isfinite(value) and signal.minimum <= value <= signal.maximum
    if signal.type == "int":
        ok = isinstance(value, int) and not isinstance(value, bool)
        return ok and signal.minimum <= value <= signal.maximum
    if signal.type == "bool":
        return isinstance(value, bool)
    return isinstance(value, str)


VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-100, 200),
    st.booleans(),
    st.text(max_size=5),
    st.none(),
    st.lists(st.integers(), max_size=2),
)


@settings(max_examples=200, deadline=None)
@given(payload=st.dictionaries(st.sampled_from(sorted(PROBE.signals) + ["other"]), VALUES))
def test_telegraf_stores_exactly_the_valid_values(payload):
    tg, stored = started_telegraf()
    result = tg.digest("box/sensors", payload, 1.0)
    expected = {
        k: v for k, v in payload.items() if k in PROBE.signals and valid(PROBE.signals[k], v)
    }
    assert result == expected
    assert stored == ([expected] if expected else [])
    bad = sum(
        1 for k, v in payload.items() if k in PROBE.signals and not valid(PROBE.signals[k], v)
    )
    assert sum(tg.rejected.values()) == bad


UNBOUNDED = Probe(
    "box/free",
    {
        "x": Signal("x", "float"),
        "n": Signal("n", "int"),
        "low": Signal("low", "float", minimum=0.0),
        "j": Signal("j", "json"),
        "s": Signal("s", "str"),
        "b": Signal("b", "bool"),
    },
)


class Level(int):
    pass


class Name(str):
    pass


class Reading(float):
    pass


# the edges of the fast test: bounds, non-finite numbers, ints without a float (10**400)
EDGES = [math.inf, -math.inf, math.nan, -0.0, 0, 1e308, -40.0, -40.000001, 150.0, 150.5, 10]
EDGES += [11, -1, 2**1000, -(2**1000), 10**400, -(10**400), True, False, "", None]
ODD = st.one_of(
    st.sampled_from(EDGES),
    VALUES,
    st.integers(),
    st.integers(-3, 3).map(Level),
    st.text(max_size=3).map(Name),
    st.sampled_from(EDGES[:6]).map(Reading),
)


@settings(max_examples=400, deadline=None)
@given(data=st.data(), probe=st.sampled_from([PROBE, UNBOUNDED]))
def test_telegraf_fast_checks_agree_with_the_full_check(data, probe):
    # digest() passes the common good value with one test; what it stores (and its type), what
    # it refuses and why, and what it raises must be what the full check says
    payload = data.draw(st.dictionaries(st.sampled_from([*probe.signals, "y"]), ODD))
    tg = Telegraf([probe], lambda values, time: None)
    tg.send("configure")
    expected, problems, raised = {}, Counter(), None
    for key, signal in probe.signals.items():
        if key in payload:
            value = payload[key]
            try:
                problem = _check_value(signal, value)
            except Exception as exc:  # a huge int has no float for math.isfinite
                raised = type(exc)
                break
            if problem:
                problems[problem] += 1
            else:
                expected[key] = float(value) if signal.type == "float" else value
    if raised is not None:
        with pytest.raises(raised):
            tg.digest(probe.topic, payload, 1.0)
        return
    result = tg.digest(probe.topic, payload, 1.0)
    assert result == expected
    assert [type(v) for v in result.values()] == [type(v) for v in expected.values()]
    assert tg.rejected == problems


def test_telegraf_refuses_unroutable_data_and_works_only_when_initialized():
    tg, stored = started_telegraf()
    assert tg.digest("elsewhere", {"temperature": 1.0}, 0) == {}
    assert tg.digest("box/sensors", ["not", "a", "dict"], 0) == {}
    assert tg.rejected["unroutable"] == 2
    tg.send("failed", reason="test")
    assert tg.mode == "fault"
    assert tg.digest("box/sensors", {"temperature": 20.0}, 0) == {}
    assert tg.rejected["not running"] == 1 and stored == []


def test_checker_sends_only_applicable_actions_to_known_effectors():
    sent = []
    mode = {"now": "docked"}
    tc = TrustworthinessChecker(
        monitors=[],
        effectors={"wheels": Effector("wheels", "robot/wheels", ("navigate",))},
        send=lambda effector, action: sent.append((effector.name, action.payload)),
        mode_of=lambda: mode["now"],
    )
    assert tc.register_action(Action("wheels", {"v": 1}))[0] is False  # not started yet
    tc.send("configure")
    ok, why = tc.register_action(Action("wheels", {"v": 1}))
    assert not ok and "mode 'docked'" in why
    ok, why = tc.register_action(Action("laser", {"on": True}))
    assert not ok and "unknown effector" in why
    mode["now"] = "navigate"
    assert tc.register_action(Action("wheels", {"v": 2}))[0] is True
    assert sent == [("wheels", {"v": 2})]
    assert "monitoring" in tc.configuration  # the chart went checking_action -> monitoring


def test_log_sinks_file_and_bus(hotbox, tmp_path):
    log_file = tmp_path / "rasm.log"
    hotbox.logging = {"level": "info", "sinks": [f"file:{log_file}", "bus:rasm/log"]}
    platform = Platform(hotbox, clock="simulated", knowledge="memory")
    platform.build()
    published = []
    platform.transport.subscribe("rasm/log", lambda message: published.append(message.payload))

    class Crashing:
        def plan(self, ctx):
            raise RuntimeError("planner bug 42")

    platform.ao.components["plan"] = Crashing()
    platform.run(12)
    text = log_file.read_text()
    assert "plan stage failed: RuntimeError: planner bug 42" in text
    assert any("planner bug 42" in p["message"] and p["level"] == "ERROR" for p in published)
    assert platform.lt.counts["ERROR"] >= 1
    # the sinks are detached at termination
    assert not platform.lt.handlers
    json.dumps(published)  # bus payloads are plain JSON


class _Faulty:
    properties = ["faulty"]

    def step(self, time, record):
        raise RuntimeError("broken monitor")


def test_checker_hands_verdicts_to_the_observers_listed_now_and_a_faulty_monitor_is_in_error():
    from rasm.properties import compile_properties

    monitor = compile_properties("input x: float\nproperty low: always (x < 1)\n")
    observers: list = []
    called = []
    tc = TrustworthinessChecker(
        monitors=[_Faulty(), monitor],
        effectors={},
        send=lambda effector, action: None,
        mode_of=lambda: None,
        on_verdict=called.append,
        observers=observers,
    )
    first = tc.observe(0.0, {"x": 0.5})
    # the faulty monitor's properties are in error for the record; the others are judged
    assert [(v.property, v.value) for v in first] == [("faulty", False), ("low", True)]
    assert "RuntimeError: broken monitor" in first[0].error and first[1].error is None
    assert tc.monitor_failures == 1
    seen: list = []
    observers.append(seen.append)  # added during the run: called from the next record on
    second = tc.observe(1.0, {"x": 2.0})
    assert seen == second and called == first + second
    assert {name: v.value for name, v in tc.latest.items()} == {"faulty": False, "low": False}
    assert tc.outcomes["low"].state == "violated" and tc.outcomes["low"].violations == 1
    assert tc.outcomes["faulty"].state == "error" and tc.outcomes["faulty"].errors == 2
    assert tc.monitor_failures == 2


def test_platform_verdict_observers_added_while_running_see_the_live_verdicts(hotbox):
    platform = Platform(hotbox, clock="simulated", knowledge="memory")
    seen: list = []
    platform.start()
    platform.on_verdict.append(seen.append)
    try:
        platform.scheduler.run_until(platform.clock.time + 2.0)
    finally:
        platform.stop()
    assert {v.property for v in seen} >= {"temperature_band", "stage_order"}
    assert all(v.value is True for v in seen)


def test_knowledge_manager_batches_refuse_each_bad_value_and_everything_when_not_running():
    from rasm.errors import PlatformError
    from rasm.knowledge import KnowledgeBase
    from rasm.platform.knowledge_manager import KnowledgeManager

    class OneAtATime:  # a store without register_values
        def __init__(self):
            self.kb = KnowledgeBase()
            self.kb.declare("speed", "float", minimum=0.0)

        def register_knowledge(self, key, value, time):
            return self.kb.register_knowledge(key, value, time)

        def read_knowledge(self, key, default=None):
            return self.kb.read_knowledge(key, default)

    for store in (OneAtATime(), OneAtATime().kb):
        km = KnowledgeManager(store)
        refused = km.register_values({"speed": 1.0, "mode": "x"}, 0.0)
        assert list(refused) == ["speed", "mode"]
        assert all(isinstance(e, PlatformError) for e in refused.values())
        km.send("configure")
        refused = km.register_values({"speed": -1.0, "mode": "x"}, 1.0)
        assert list(refused) == ["speed"] and "below the declared minimum" in str(refused["speed"])
        assert km.read_knowledge("mode") == "x"


def test_a_chart_file_is_loaded_once_and_again_when_its_bytes_change(tmp_path):
    from rasm.platform.block import shared_chart

    text = """\
statechart:
  name: toggle
  root state:
    name: root
    initial: off
    states:
      - name: off
        transitions: [{target: on, event: flip}]
      - name: on
        transitions: [{target: off, event: flip}]
"""
    path = tmp_path / "toggle.yaml"
    path.write_text(text, encoding="utf-8")
    first = shared_chart(path)
    assert shared_chart(path) is first  # shared: blocks never change a chart
    # same length, rewritten at once (the modification time may not move): loaded again
    path.write_text(text.replace("initial: off", "initial: on "), encoding="utf-8")
    changed = shared_chart(path)
    assert changed is not first
    assert changed.state_for("root").initial == "on"
    assert first.state_for("root").initial == "off"
