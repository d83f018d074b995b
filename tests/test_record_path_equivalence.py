"""The per-record fast paths give what the general code they replace gives, for any input.

Each test keeps the straightforward version (as it was written before it was made faster) and
checks the fast one against it: knowledge read under one lock, the Page-Hinkley update with its
min() and statistic written out, the Hotbox simulator's step with min/max written out.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.values import Declaration, make_check
from rasm.twin import PageHinkley

SETTINGS = settings(max_examples=300, deadline=None, database=None)
FLOATS = st.floats(allow_nan=True, allow_infinity=True)


def _same(a, b) -> bool:
    """Equal and of the same type, a nan equal to a nan."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and math.isnan(a):
        return math.isnan(b)
    return a == b


# -------------------------------------------------------------------- knowledge: read_values

KEYS = st.sampled_from(["a", "b", "c", "missing"])


@SETTINGS
@given(
    st.lists(st.tuples(KEYS, st.floats(-10, 10) | st.booleans() | st.text(max_size=3))),
    st.lists(KEYS, max_size=5),
    st.none() | st.integers(),
)
def test_read_values_is_read_knowledge_of_each_key(writes, keys, default):
    kb = KnowledgeBase(default_history=3)
    for time, (key, value) in enumerate(writes):
        try:
            kb.register_knowledge(key, value, float(time))
        except Exception:  # a value of another type than the key's first: refused, as ever
            pass
    assert kb.read_values(keys, default) == {k: kb.read_knowledge(k, default) for k in keys}


BOUNDS = st.none() | st.integers(-5, 5) | st.floats(-5, 5) | st.sampled_from([-math.inf, math.inf])
ANY_VALUE = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(-(2**1100), 2**1100)
    | FLOATS
    | st.text(max_size=3)
    | st.lists(st.integers(), max_size=2)
)


@SETTINGS
@given(st.sampled_from(["float", "int", "bool", "str", "json"]), BOUNDS, BOUNDS, ANY_VALUE)
def test_a_stored_value_is_what_its_declarations_check_makes_of_it(kind, lo, hi, value):
    numeric = kind in ("float", "int")
    if numeric and lo is not None and hi is not None and lo > hi:
        lo, hi = hi, lo
    decl = Declaration("k", kind, minimum=lo if numeric else None, maximum=hi if numeric else None)
    kb = KnowledgeBase()
    kb.declare("k", kind, minimum=decl.minimum, maximum=decl.maximum)
    try:
        expected = make_check(decl)(value)
    except KnowledgeError as exc:
        with pytest.raises(KnowledgeError) as raised:
            kb.register_knowledge("k", value, 1.0)
        assert str(raised.value) == str(exc)
        assert kb.register_values({"k": value}, 1.0)["k"].args == exc.args
        return
    assert _same(kb.register_knowledge("k", value, 1.0).value, expected)
    assert kb.register_values({"k": value}, 2.0) == {}
    assert _same(kb.read_knowledge("k"), expected)


class _OwnReads(KnowledgeBase):
    """A store that reads its own way (as Redis does): read_values must ask it per key."""

    def read_knowledge(self, key, default=None):
        return ("own", key, default)


def test_read_values_asks_a_store_that_reads_its_own_way():
    kb = _OwnReads()
    assert kb.read_values(["x", "y"], 0) == {"x": ("own", "x", 0), "y": ("own", "y", 0)}


# -------------------------------------------------------------------- twin: Page-Hinkley


class _ReferencePageHinkley:
    """PageHinkley.update as first written (attributes, min(), the statistic property)."""

    def __init__(self, delta, threshold, min_samples):
        self.delta, self.threshold, self.min_samples = delta, threshold, min_samples
        self.detections = 0
        self.reset()

    def reset(self):
        self.samples, self.mean, self.cumulative, self.minimum = 0, 0.0, 0.0, 0.0

    def update(self, x):
        self.samples += 1
        self.mean += (x - self.mean) / self.samples
        self.cumulative += x - self.mean - self.delta
        self.minimum = min(self.minimum, self.cumulative)
        if self.samples >= self.min_samples and self.cumulative - self.minimum > self.threshold:
            self.detections += 1
            self.reset()
            return True
        return False


@SETTINGS
@given(
    st.lists(FLOATS | st.floats(0, 1), max_size=80),
    st.floats(0, 1),
    st.floats(0.01, 3),
    st.integers(1, 10),
)
def test_page_hinkley_update_is_the_reference_update(xs, delta, threshold, min_samples):
    fast = PageHinkley(delta=delta, threshold=threshold, min_samples=min_samples)
    slow = _ReferencePageHinkley(delta, threshold, min_samples)
    for x in xs:
        assert fast.update(x) == slow.update(x)
        for name in ("samples", "mean", "cumulative", "minimum", "detections"):
            assert _same(getattr(fast, name), getattr(slow, name)), name
    assert _same(fast.statistic, slow.cumulative - slow.minimum)


# -------------------------------------------------------------------- Hotbox simulator step


def _hotbox_components():
    path = Path(__file__).resolve().parents[1] / "examples" / "hotbox" / "components.py"
    spec = importlib.util.spec_from_file_location("hotbox_components_under_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _reference_step(sim, time: float, dt: float) -> dict:
    """HotboxSimulator.step as first written (min/max calls, attributes read each time)."""
    while sim.content_changes and sim.content_changes[0][0] <= time:
        sim.capacity = sim.content_changes.pop(0)[1]
    lid = sim.lid_open(time)
    loss = sim.LOSS_OPEN if lid else sim.LOSS_CLOSED
    feed_forward = sim.LOSS_CLOSED * (sim.settings["setpoint"] - sim.AMBIENT)
    wanted = feed_forward + sim.GAIN * (sim.settings["setpoint"] - sim.temperature)
    sim.power = min(max(wanted, 0.0), sim.settings["power_limit"])
    sim.temperature += dt * (sim.power - loss * (sim.temperature - sim.AMBIENT)) / sim.capacity
    measured = sim.temperature + sim.rng.gauss(0.0, 0.02)
    return {
        "hotbox/sensors": {
            "temperature": round(measured, 4),
            "lid_open": lid,
            "heater_power": round(sim.power, 3),
            "heater_mode": sim.settings["mode"],
            "setpoint": sim.settings["setpoint"],
        }
    }


LIMITS = st.floats(0, 200) | st.integers(0, 200) | st.sampled_from([math.nan, math.inf])


@SETTINGS
@given(
    st.floats(-50, 150) | st.sampled_from([math.nan]),
    st.floats(0, 60) | st.integers(0, 60),
    LIMITS,
    st.integers(0, 3),
    st.lists(st.tuples(st.floats(0, 5), st.floats(10, 1000)), max_size=2),
)
def test_the_simulator_step_is_the_reference_step(temperature, setpoint, limit, seed, changes):
    module = _hotbox_components()
    scenario = {
        "initial_temperature": 37.5,
        "content_change": [list(c) for c in changes],
        "first_lid_opening": 1.0,
    }
    fast = module.HotboxSimulator(scenario, seed=seed)
    slow = module.HotboxSimulator(scenario, seed=seed)
    for sim in (fast, slow):
        sim.temperature = temperature
        sim.apply("heater", {"setpoint": setpoint, "power_limit": limit}, 0.0)
    for k in range(30):
        got, want = fast.step(0.1 * k, 0.1), _reference_step(slow, 0.1 * k, 0.1)
        assert list(got) == list(want)
        for name, value in want["hotbox/sensors"].items():
            assert _same(got["hotbox/sensors"][name], value), name
        assert _same(fast.power, slow.power) and _same(fast.temperature, slow.temperature)
