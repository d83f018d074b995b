"""The two Hotbox demonstrators (examples/hotbox/app.fallback.yaml and app.repair.yaml) do what
docs/runtime.md says, seeded: the fallback engages and hands back with its guarantees satisfied,
and a repaired plan is executed where the same app without repair cancels its adaptations."""

from __future__ import annotations

from pathlib import Path

from rasm.platform.manifest import load_manifest
from rasm.testing import run_app

HOTBOX = Path(__file__).resolve().parents[2] / "examples" / "hotbox"


def test_the_fallback_engages_and_hands_back_with_its_guarantees():
    trace = run_app(HOTBOX / "app.fallback.yaml", seed=1, duration=80)
    switches = [(r["time"], r["fallback"]) for r in trace if "fallback" in r]
    assert switches == [(15.6, "engaged"), (30.9, "released"), (55.1, "engaged"),
                        (71.4, "released")]
    assert [r["time"] for r in trace if r.get("corrective")] == [20.5, 60.5]
    verdicts = trace.summary.verdicts
    assert verdicts["fallback_in_time"] == "satisfied"
    assert verdicts["hand_back_after_dwell"] == "satisfied"
    assert verdicts["execute_only_legitimate_plans"] == "satisfied"
    assert verdicts["temperature_band"] == "violated"  # the scenario: the lid stays open
    assert trace.summary.fallback_engagements == 2


def test_a_fallback_engaged_before_any_plan_keeps_the_platforms_guarantees():
    """The box starts cold: the fallback engages at t=0, before the loop has planned anything.
    Its plan is legitimate by proof, and its first records say so before its action goes out."""
    scenario = {**load_manifest(HOTBOX / "app.fallback.yaml").scenario, "initial_temperature": 30}
    trace = run_app(HOTBOX / "app.fallback.yaml", seed=1, duration=10, scenario=scenario)
    assert [(r["time"], r["fallback"]) for r in trace if "fallback" in r][0] == (0, "engaged")
    first = [(r.get("plan"), key) for r in trace if r["time"] == 0
             for key in ("planned", "legitimate", "trusted", "executed") if r.get(key)]
    assert first == [("f1", "legitimate"), ("f1", "trusted"), ("f1", "executed")]
    verdicts = trace.summary.verdicts
    assert verdicts["execute_only_legitimate_plans"] == "satisfied"
    assert verdicts["rejected_plans_stay_rejected"] == "satisfied"


def test_a_repaired_plan_is_executed_instead_of_a_cancelled_adaptation():
    # 36 s: the boost at 9 s, on a heater limited to 65 W, does not warm the box back within
    # the 30 s back_to_normal allows (that is the weak heater's, not the repair's)
    trace = run_app(HOTBOX / "app.repair.yaml", seed=1, duration=36)
    repaired = [r for r in trace if "repaired_from" in r]
    assert [(r["time"], r["plan"], r["repaired_from"], r["power_limit"]) for r in repaired] == [
        (9.0, "p2", "p1", 65.0)
    ]
    assert "p2" in {r["plan"] for r in trace if r.get("executed")}
    stats = trace.summary.stats
    assert (stats.anomalies, stats.executed, stats.cancelled) == (1, 1, 0)
    assert trace.summary.ok
    without = run_app(HOTBOX / "app.repair.yaml", seed=1, duration=36, repair=False)
    stats = without.summary.stats
    assert (stats.anomalies, stats.rejected, stats.executed, stats.cancelled) == (55, 110, 0, 55)
    assert without.summary.verdicts["timely_adaptation"] == "violated"
