"""The Hotbox under generated lid schedules: timely adaptation holds; a slow planner is caught."""

from __future__ import annotations

import time

import pytest
from hypothesis import Phase, find, given, settings

from rasm.testing import assert_properties, check_trace, run_app, scenarios

from .conftest import HOTBOX, HOTBOX_PROPS

DURATION = 30  # simulated seconds; a run costs about 0.2 s here
# no explain phase: it re-runs the failing example under a tracer, costly for a whole loop
PHASES = [Phase.explicit, Phase.reuse, Phase.generate, Phase.shrink]


@pytest.mark.slow
@settings(max_examples=10, deadline=None, phases=PHASES, database=None)
@given(scenario=scenarios(HOTBOX, duration=DURATION))
def test_timely_adaptation_holds_for_any_lid_schedule(scenario):
    trace = run_app(HOTBOX, seed=3, duration=DURATION, scenario=scenario)
    assert trace.scenario == scenario
    assert_properties(HOTBOX_PROPS, trace, only=["timely_adaptation"])
    # the trace is the adaptation trace: the lid schedule shows in it, and every anomaly
    # that left time to answer was answered
    opened = [t for t, lid in trace.values("lid_open") if lid]
    assert opened and min(opened) >= scenario["openings"][0][0]


class SlowPlanner:
    """Plans boosts like the Hotbox's planner, but too slowly (an expensive search).

    The sleep is the defect under test, not a synchronisation: a boost plan takes 30 ms of wall
    time, twice the 15.6 ms stage budget the test gives the loop, so it always overruns.
    """

    def plan(self, ctx):
        if ctx.anomaly.data.get("want") == "boost":
            time.sleep(0.03)
        return {"mode": "normal", "setpoint": 37.5, "power_limit": 60.0}


BUDGET = 2**-6  # 15.6 ms: a short budget keeps each overrun cheap in wall-clock time


@pytest.mark.slow
def test_a_slow_planner_is_caught_and_shrunk_to_one_short_opening():
    runs = []

    def too_late(scenario):
        trace = run_app(
            HOTBOX,
            seed=3,
            duration=20,
            scenario=scenario,
            components={"plan": SlowPlanner()},
            stage_budget=BUDGET,
        )
        runs.append(scenario)
        report = check_trace(HOTBOX_PROPS, trace, explain=False)
        return any(p.name == "timely_adaptation" and p.violations for p in report.properties)

    minimal = find(
        scenarios(HOTBOX, duration=20),
        too_late,
        settings=settings(max_examples=15, deadline=None, phases=PHASES, database=None,
                          derandomize=True),
    )
    openings = minimal["openings"]
    assert len(openings) == 1, minimal
    start, length = openings[0]
    assert start == 0.0 and length <= 5.0, minimal  # one short, early opening suffices
    # the same schedule with the app's own planner is answered in time: the planner is the bug
    good = run_app(HOTBOX, seed=3, duration=20, scenario=minimal, stage_budget=BUDGET)
    assert_properties(HOTBOX_PROPS, good, only=["timely_adaptation"])
    assert len(runs) < 80  # shrinking stayed cheap


def test_scenarios_of_the_hotbox_are_lid_openings_within_the_run():
    @settings(max_examples=40, deadline=None, database=None)
    @given(scenarios(HOTBOX, duration=DURATION))
    def check(scenario):
        assert set(scenario) == {"openings"}
        openings = scenario["openings"]
        assert 1 <= len(openings) <= 3
        end = -1.0
        for start, length in openings:
            assert end <= start <= DURATION - 5 and 0.5 <= length <= 15
            end = start + length

    check()


def test_run_app_leaves_nothing_on_disk_but_the_trace_it_was_asked_for(tmp_path, monkeypatch):
    import shutil

    monkeypatch.chdir(tmp_path)  # where a run's state (.rasm/<app>/) would go
    app = tmp_path / "hotbox"
    shutil.copytree(HOTBOX, app, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    before = {p.relative_to(tmp_path) for p in tmp_path.rglob("*")}
    trace = run_app(app, seed=1, duration=3, trace=tmp_path / "run.jsonl")
    assert len(trace) > 0
    after = {p.relative_to(tmp_path) for p in tmp_path.rglob("*") if "__pycache__" not in p.parts}
    assert after - before == {tmp_path.joinpath("run.jsonl").relative_to(tmp_path)}
    # the timing file is written again when asked for
    run_app(app, seed=1, duration=3, timing=f"file:{tmp_path / 'timing.lp'}")
    assert "maple_stage" in (tmp_path / "timing.lp").read_text()


def test_a_simulated_run_starts_its_timing_file_afresh(tmp_path, monkeypatch):
    from rasm import Platform, RunOptions
    from rasm.platform.manifest import load_manifest

    monkeypatch.chdir(tmp_path)
    sizes = []
    for _ in range(2):
        Platform(load_manifest(HOTBOX), RunOptions(clock="simulated", seed=1,
                                                   knowledge="memory")).run(3)
        sizes.append((tmp_path / ".rasm" / "hotbox" / "timing.lp").stat().st_size)
    # the same seed writes the same points: a second run replaces the first, not adds to it
    assert sizes[0] > 0 and abs(sizes[1] - sizes[0]) < sizes[0] / 2
