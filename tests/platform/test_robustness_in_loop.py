"""Robustness in the loop (SPEC §12): the Trustworthiness Checker writes each property's
robustness into knowledge as ``robustness_<property>``, and the trace carries it."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.platform.manifest import load_manifest
from rasm.platform.signals import app_problems
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.properties import compile_properties
from rasm.trace import read_trace

from .conftest import HOTBOX

BAND = """input temperature: float
property band:
    always (temperature >= 34.5 and temperature <= 41.0)
"""


def checker(*monitors):
    written: list[tuple[float, dict[str, float]]] = []
    tc = TrustworthinessChecker(
        monitors=list(monitors), effectors={}, send=lambda effector, action: None,
        mode_of=lambda: None, write_robustness=lambda values, time: written.append((time, values)),
    )
    return tc, written


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(300, 450).map(lambda t: t / 10), min_size=1, max_size=20))
def test_the_checker_writes_a_pointwise_robustness_once_per_record_where_it_changed(readings):
    tc, written = checker(compile_properties(BAND, robustness=True))
    expected, last = [], None
    for i, temperature in enumerate(readings):
        tc.observe(float(i), {"temperature": temperature})
        value = min(temperature - 34.5, 41.0 - temperature)
        if value != last:
            expected.append((float(i), {"robustness_band": value}))
        last = value
    assert written == expected


@pytest.mark.parametrize("intervals", [True, "newest"])  # "newest": as the loop's monitors
def test_an_early_verdict_writes_the_lower_bound_of_its_interval_then_the_final_values(
        intervals):
    tc, written = checker(compile_properties(
        "input x: float\nproperty soon:\n    eventually[0, 2s] (x > 1)\n", robustness=True,
        intervals=intervals))
    tc.observe(0.0, {"x": 2.0})  # true at once; more records may raise the maximum: [1, inf]
    tc.observe(1.5, {"x": 0.0})  # record 1 is undecided: nothing new to write
    tc.observe(4.0, {"x": 0.5})  # record 1's window [1.5, 3.5] is over: only itself, 0 - 1
    assert written == [(0.0, {"robustness_soon": 1.0}), (4.0, {"robustness_soon": -1.0})]


def test_an_early_verdict_without_its_interval_writes_minus_infinity():
    tc, written = checker(compile_properties(
        "input x: float\nproperty soon:\n    eventually[0, 2s] (x > 1)\n", robustness=True))
    tc.observe(0.0, {"x": 2.0})  # decided, its robustness not final and no interval asked for
    assert written == [(0.0, {"robustness_soon": -math.inf})]


def test_an_error_or_a_stale_reading_writes_minus_infinity():
    tc, written = checker(compile_properties(BAND, robustness=True))
    tc.observe(0.0, {"temperature": 37.0})
    tc.set_stale({"temperature": "no reading for 2 s"}, 1.0)  # not a record: nothing written
    tc.observe(2.0, {"temperature": 37.0})
    assert written == [(0.0, {"robustness_band": 2.5}), (2.0, {"robustness_band": -math.inf})]
    assert tc.latest["band"].robustness == -math.inf  # the verdict says the same


def test_a_monitor_without_robustness_writes_nothing():
    tc, written = checker(compile_properties(BAND))
    tc.observe(0.0, {"temperature": 37.0})
    assert written == []


MARGIN = """input robustness_temperature_band: float
# reads the band's robustness: at least 0.5 °C inside the band
property keeps_margin:
    always (robustness_temperature_band >= 0.5)
"""


def test_a_hotbox_run_writes_the_band_robustness_into_knowledge_and_the_trace(tmp_path):
    margin = tmp_path / "margin.rv"
    margin.write_text(MARGIN)
    app = load_manifest(HOTBOX)
    app = dataclasses.replace(app, properties=[*app.properties, margin])
    assert app_problems(app) == []  # robustness_<property> is a signal the app provides
    trace = tmp_path / "trace.jsonl"
    platform = Platform(app, RunOptions(clock="simulated", seed=3, trace=trace, knowledge="memory"))
    summary = platform.run(20)
    records = read_trace(trace)

    # each record carries the robustness the records before it gave: the band's from the
    # temperature in force on the record before
    temperature, expected, checked = None, None, 0
    for _, record in records:
        if "robustness_temperature_band" in record:
            assert record["robustness_temperature_band"] == expected
            checked += 1
        if "temperature" in record:
            temperature = record["temperature"]
            expected = min(temperature - 34.5, 41.0 - temperature)
    assert checked > 100
    # knowledge has the newest: the last record's temperature
    knowledge = platform.managing.knowledge_manager
    assert knowledge.read_knowledge("robustness_temperature_band") == expected
    # a boolean property's robustness is infinite, and the trace writes it so
    assert {r["robustness_stage_order"] for _, r in records if "robustness_stage_order" in r} == {
        math.inf}
    # a property reading robustness is judged online, and offline on the trace alike
    assert summary.verdicts["keeps_margin"] == "satisfied"
    (offline,) = compile_properties(MARGIN).run(records)
    assert offline.start is not None and offline.values and all(offline.values)
    checker = platform.managing.trustworthiness_checker
    assert len(offline.values) == checker.outcomes["keeps_margin"].judged
