"""The TurtleBot's fallback demonstrator (examples/turtlebot/app.fallback.yaml), seeded: its spin
planner crashes from 14 s on; after three failed iterations the fallback's "stop often and look
all around" holds /spin_config, and control comes back after three clean iterations and the
3 s dwell."""

from __future__ import annotations

from pathlib import Path

import pytest

from rasm.testing import run_app

APP = Path(__file__).resolve().parents[2] / "examples" / "turtlebot" / "app.fallback.yaml"


def test_the_crashing_planner_ends_in_the_fallback_which_hands_back():
    trace = run_app(APP, seed=1, duration=30)
    switches = [(r["time"], r["fallback"]) for r in trace if "fallback" in r]
    # (the analyse chart's after(settle) holds at its deadline: the anomalies come at 15.4, 16.4
    # and 17.4, where binary arithmetic put the second and third a period later)
    assert switches == [(17.6, "engaged"), (21.2, "released")]
    failures = [r["time"] for r in trace
                if str(r.get("explanation", "")).startswith("plan stage failed")]
    # the period after the third failure
    assert len(failures) >= 3 and failures[2] <= 17.6 <= round(failures[2] + 0.2, 9)
    executed = [(r["time"], r["plan"]) for r in trace if r.get("executed")]
    assert (17.6, "f1") in executed
    assert not [plan for t, plan in executed if 17.6 <= t < 21.2 and not plan.startswith("f")]
    # the robot received the fallback's configuration and swept ±150 deg
    assert any(r.get("spin_plan") == "f1" and r.get("spin_rotation") == 150.0 for r in trace)
    assert trace.summary.verdicts["no_collision"] == "satisfied"


REPAIR = APP.with_name("app.repair.yaml")


@pytest.mark.slow
def test_repaired_spin_plans_are_executed_where_cancelled_ones_end_in_a_collision():
    trace = run_app(REPAIR, seed=1, duration=60)
    repaired = [r for r in trace if "repaired_from" in r]
    # the two debris, then three looks for clearance (statecharts/analyse.yaml)
    assert [(r["time"], r["plan"], r["repaired_from"], r["angular_velocity"]) for r in repaired] \
        == [(2.4, "p2", "p1", 45.0), (15.4, "p4", "p3", 45.0), (26.4, "p6", "p5", 45.0),
            (37.8, "p8", "p7", 45.0), (49.2, "p10", "p9", 45.0)]
    for r in repaired:  # the stop is lengthened just enough for the slower sweep to fit
        assert abs(r["angular_velocity"] * r["spin_duration"] - 4 * r["rotation"]) < 1e-6
    assert {"p2", "p4", "p6", "p8", "p10"} <= {r["plan"] for r in trace if r.get("executed")}
    assert trace.summary.ok
    without = run_app(REPAIR, seed=1, duration=60, repair=False)
    stats = without.summary.stats
    assert (stats.executed, stats.cancelled) == (0, 33)
    assert without.summary.verdicts["no_collision"] == "violated"
