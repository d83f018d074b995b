"""The TurtleBot's fallback demonstrator (examples/turtlebot/app.fallback.yaml), seeded: its spin
planner crashes from 14 s on; after three failed iterations the fallback's "stop often and look
all around" holds /spin_config, and control comes back after three clean iterations and the
3 s dwell."""

from __future__ import annotations

from pathlib import Path

from rasm.testing import run_app

APP = Path(__file__).resolve().parents[2] / "examples" / "turtlebot" / "app.fallback.yaml"


def test_the_crashing_planner_ends_in_the_fallback_which_hands_back():
    trace = run_app(APP, seed=1, duration=30)
    switches = [(r["time"], r["fallback"]) for r in trace if "fallback" in r]
    assert switches == [(17.8, "engaged"), (21.4, "released")]
    failures = [r["time"] for r in trace
                if str(r.get("explanation", "")).startswith("plan stage failed")]
    assert len(failures) >= 3 and failures[2] <= 17.8 <= failures[2] + 0.2  # the next period
    executed = [(r["time"], r["plan"]) for r in trace if r.get("executed")]
    assert (17.8, "f1") in executed
    assert not [plan for t, plan in executed if 17.8 <= t < 21.4 and not plan.startswith("f")]
    # the robot received the fallback's configuration and swept ±150 deg
    assert any(r.get("spin_plan") == "f1" and r.get("spin_rotation") == 150.0 for r in trace)
    assert trace.summary.verdicts["no_collision"] == "satisfied"
