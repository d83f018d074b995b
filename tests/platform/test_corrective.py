"""Corrective actions under a veto, on the Hotbox with a fallback (examples/hotbox/
app.fallback.yaml): while the band is violated only the fallback's actions and actions the twin
predicts bring the band back sooner than doing nothing reach the heater, and the trace says so."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.errors import SourceErrors
from rasm.platform.corrective import recovery_times
from rasm.properties import load_specification
from rasm.testing import run_app

APP = Path(__file__).resolve().parents[2] / "examples" / "hotbox" / "app.fallback.yaml"


def engaged_spans(trace):
    """The records while the fallback holds, as a list of records per engagement."""
    spans, current = [], None
    for record in trace:
        if record.get("fallback") == "engaged":
            current = []
            spans.append(current)
        elif record.get("fallback") == "released":
            current = None
        elif current is not None:
            current.append(record)
    return spans


def test_only_fallback_and_corrective_actions_act_while_the_veto_holds():
    trace = run_app(APP, seed=1, duration=40)
    spans = engaged_spans(trace)
    assert spans, "the scenario's lid opening leaves the band: the fallback engages"
    corrective = {r["plan"]: r["explanation"] for r in trace if r.get("corrective")}
    assert corrective, "the twin predicts boost brings the band back sooner"
    for span in spans:
        for record in span:
            if record.get("executed"):
                plan = record["plan"]
                assert plan.startswith("f") or plan in corrective, record
    for why in corrective.values():
        assert why.startswith("the twin predicts temperature_band holds again ")


def test_without_corrective_actions_nothing_but_the_fallback_acts_while_it_holds():
    trace = run_app(APP, seed=1, duration=40, corrective=False)
    spans = engaged_spans(trace)
    assert spans and not any(r.get("corrective") for r in trace)
    for span in spans:
        executed = [r["plan"] for r in span if r.get("executed")]
        assert all(plan.startswith("f") for plan in executed), executed
        held = [r for r in span if r.get("dropped")]
        assert held and all(r["explanation"].startswith("the fallback holds the effectors")
                            for r in held)


def test_corrective_actions_need_a_twin(tmp_path):
    app = tmp_path / "hotbox"
    shutil.copytree(APP.parent, app, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    text = APP.read_text()
    without_twin = text[: text.index("twin:\n")] + text[text.index("properties:\n") :]
    (app / "app.fallback.yaml").write_text(without_twin)
    with pytest.raises(SourceErrors) as caught:
        Platform(app / "app.fallback.yaml", RunOptions(clock="simulated",
                                                       knowledge="memory")).build()
    assert "app.fallback.yaml:" in str(caught.value)
    assert "corrective actions need a digital twin" in str(caught.value)


SPEC = load_specification("input ok: bool\nproperty p:\n    always (ok)\n", source="p.rv")


@given(st.lists(st.booleans(), min_size=1, max_size=20))
def test_recovery_is_the_first_record_after_the_last_violation(values):
    records = [(float(i + 1), {"ok": v}) for i, v in enumerate(values)]
    found = recovery_times([SPEC], records, ["p"])["p"]
    if all(values):
        assert found == 1.0
    elif not values[-1]:
        assert found == math.inf
    else:
        last_false = max(i for i, v in enumerate(values) if not v)
        assert found == float(last_false + 2)
        assert all(values[last_false + 1:])
