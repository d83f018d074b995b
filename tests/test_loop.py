"""rasm.loop: the vocabulary is the one the running loop writes in its trace."""

from __future__ import annotations

from pathlib import Path

import pytest

from rasm.errors import Misfit
from rasm.loop import EVENTS, LOOP_KEYS, LOOP_SIGNAL_TYPES, STAGES, robustness_key
from rasm.platform.signals import checked_properties
from rasm.testing import run_app
from rasm.testing.apps import app_manifest
from rasm.values import fit

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def hotbox():
    return run_app(EXAMPLES / "hotbox", seed=1, duration=120)


def test_every_key_of_a_trace_is_the_loops_or_the_apps(hotbox):
    manifest = app_manifest(EXAMPLES / "hotbox")
    # with each checked property's robustness, which the Trustworthiness Checker writes
    robustness = {robustness_key(name) for name in checked_properties(manifest)}
    app_keys = {*manifest.signals, *manifest.produces["monitor"], "twin_residual", *robustness}
    plan_fields = set(manifest.produces["plan"])
    for record in hotbox:
        extra = set(record) - LOOP_KEYS - app_keys
        if record.get("planned") is True:
            extra -= plan_fields  # a plan record carries the plan's fields
        assert not extra, record
        assert not (LOOP_KEYS & app_keys)


def test_the_loop_writes_each_of_its_keys_with_its_declared_type(hotbox):
    seen = set()
    for record in hotbox:
        for key in LOOP_KEYS.intersection(record):
            seen.add(key)
            try:
                fit(record[key], LOOP_SIGNAL_TYPES[key], int_as_float=False)
            except Misfit as misfit:
                pytest.fail(f"{key} = {record[key]!r} in {record}: {misfit}")
    assert {"time", "stage", "duration", "plan", "twin_model_version"} <= seen


def test_stages_come_in_loop_order_and_events_are_the_loops(hotbox):
    stages = [r["stage"] for r in hotbox if "stage" in r]
    assert set(stages) == set(STAGES)
    iterations = " ".join(stages).split("monitor")[1:]  # each iteration starts with the Monitor
    for iteration in iterations:
        order = [STAGES.index(stage) for stage in ["monitor", *iteration.split()]]
        assert order == sorted(order), iteration
    events = [e for r in hotbox for e in EVENTS if r.get(e) is True]
    # one adaptation meets its events in the order EVENTS lists them
    adaptation = events[events.index("anomaly") : events.index("executed") + 1]
    assert adaptation == sorted(adaptation, key=EVENTS.index)
    assert {"anomaly", "planned", "legitimate", "trusted", "executed"} <= set(events)
