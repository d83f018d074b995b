"""The safe fallback (Simplex), end to end on the simulated clock: its triggers engage it within
its deadline, nothing but its actions reaches an effector while it holds, it hands control back
only after no trigger held for the dwell time, and an app whose fallback actions z3 cannot prove
legitimate in every context is refused before it runs."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.errors import SourceErrors
from rasm.platform.components import Plan
from rasm.testing import run_app

from .guarded import write_guarded_app

RULES = """variables:
  level: {type: int, min: 0, max: 5}
  speed: {type: real, min: 0, max: 10}
rules:
  - name: gentle
    require: level <= 3
  - name: calm_when_fast
    when: speed > 1.0
    require: level <= 1
"""

FALLBACK = """
rules: rules/robot.yaml
fallback:
  actions: {{motor: {{level: {level}}}}}
  when: [{when}]
  after_failures: {after}
  dwell: {dwell}
"""

PERIOD = 0.5


def write_app(folder, *, level=0, when="veto, stage_failures", after=3, dwell=2.0, veto=("slow",),
              staleness=None, period=PERIOD):
    app = write_guarded_app(folder, period=period, veto=veto, staleness=staleness)
    (app / "rules").mkdir(exist_ok=True)
    (app / "rules" / "robot.yaml").write_text(RULES)
    text = (app / "app.yaml").read_text().replace(
        "plan: components:Level",
        "plan: {component: components:Level, produces: {level: int}}",
    )
    (app / "app.yaml").write_text(
        text + FALLBACK.format(level=level, when=when, after=after, dwell=dwell)
    )
    return app


def switches(trace):
    """(time, "engaged" | "released") of every switch of the fallback."""
    return [(r["time"], r["fallback"]) for r in trace if "fallback" in r]


def executed_plans(trace):
    return [(r["time"], r["plan"]) for r in trace if r.get("executed")]


def assert_guarantees(trace):
    """The platform's guarantees hold with the fallback's actions among the loop's: nothing
    executed unless legitimate and registered, no rejected plan executed (SPEC §9)."""
    verdicts = trace.summary.verdicts
    assert verdicts["execute_only_legitimate_plans"] == "satisfied"
    assert verdicts["rejected_plans_stay_rejected"] == "satisfied"


def assert_only_fallback_while_engaged(trace):
    """Between an engagement and its release, every executed action is a fallback action."""
    engaged = False
    for record in trace:
        if record.get("fallback") == "engaged":
            engaged = True
        elif record.get("fallback") == "released":
            engaged = False
        if engaged and record.get("executed"):
            assert record["plan"].startswith("f"), record


# ---------------------------------------------------------------- a violated veto property


def test_a_violated_veto_engages_the_fallback_at_once_and_hands_back_after_the_dwell(tmp_path):
    app = write_app(tmp_path / "app", dwell=2.0)
    trace = run_app(app, seed=1, duration=20, scenario={"fast": [[5.0, 9.0]]})
    assert switches(trace) == [(5.0, "engaged"), (11.0, "released")]
    # the first record with speed 2.0 is at t=5.0: engaged on it; the fallback action went out
    assert ("f1" in {plan for _, plan in executed_plans(trace)})
    fallback_sent = [t for t, plan in executed_plans(trace) if plan == "f1"]
    assert fallback_sent == [5.0]
    assert_only_fallback_while_engaged(trace)
    # hand-back: the last fast record is before 9.0, then 2 s without a trigger (at the tick
    # that found it clear, t=9.0) — never earlier
    last_fast = max(r["time"] for r in trace if r.get("speed") == 2.0)
    assert last_fast < 9.0 and 11.0 - 9.0 >= 2.0
    # the loop's own actions come back after the release
    assert any(t > 11.0 and not plan.startswith("f") for t, plan in executed_plans(trace))
    # the fallback action was checked like any other
    trusted = {(r["time"], r["plan"]) for r in trace if r.get("trusted")}
    assert (5.0, "f1") in trusted


def test_a_trigger_while_recovering_engages_again_without_handing_back(tmp_path):
    app = write_app(tmp_path / "app", dwell=3.0)
    trace = run_app(app, seed=1, duration=20, scenario={"fast": [[5.0, 6.0], [7.0, 8.0]]})
    # 6.0..7.0 is shorter than the dwell: one engagement, one release after the second window
    assert switches(trace) == [(5.0, "engaged"), (11.0, "released")]
    assert_only_fallback_while_engaged(trace)


def test_the_dwell_ends_at_its_deadline_whatever_the_time_it_began(tmp_path):
    # at 10 Hz the trigger clears at 7.7 (a clock moved in binary sums of 0.1): 2 s later, at
    # 9.7, control goes back, where binary arithmetic finds 9.7 - 2 < 7.7 and never wakes again
    app = write_app(tmp_path / "app", dwell=2.0, period=0.1)
    trace = run_app(app, seed=1, duration=12, scenario={"fast": [[5.0, 7.65]]})
    assert max(r["time"] for r in trace if r.get("speed") == 2.0) == 7.6
    assert switches(trace) == [(5.0, "engaged"), (9.7, "released")]
    assert any(t > 9.7 and not plan.startswith("f") for t, plan in executed_plans(trace))


# ---------------------------------------------------------------- faulty planners


class Raises:
    def plan(self, ctx):
        raise RuntimeError("planner crashed")


class Garbage:
    def plan(self, ctx):
        return 42


class Nothing:
    def plan(self, ctx):
        return None


class BreaksRules:
    def plan(self, ctx):
        return Plan({"level": 5})


class Overruns:
    def plan(self, ctx):
        time.sleep(0.03)  # over the 0.02 s budget this test gives the stage
        return Plan({"level": 1})


FAULTS = {"raises": Raises, "garbage": Garbage, "nothing": Nothing, "breaks": BreaksRules}


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fault=st.sampled_from(sorted(FAULTS)), after=st.integers(1, 4), start=st.integers(2, 10))
def test_a_faulty_planner_always_ends_in_fallback_within_its_deadline(
    tmp_path_factory, fault, after, start
):
    app = write_app(tmp_path_factory.mktemp("app"), when="stage_failures", after=after)

    class TurnsFaulty(FAULTS[fault]):
        def plan(self, ctx):
            if ctx.time < start:
                return Plan({"level": 1})
            return super().plan(ctx)

    trace = run_app(app, seed=1, duration=start + 10, components={"plan": TurnsFaulty()})
    engaged = [t for t, what in switches(trace) if what == "engaged"]
    assert engaged, f"{fault}: the fallback never engaged"
    # the deadline: the tick after the after-th failed iteration, the first at or after start
    first_faulty = min(t for t in (r["time"] for r in trace if r.get("stage") == "plan")
                       if t >= start)
    assert first_faulty <= engaged[0] <= first_faulty + after * PERIOD + 1e-9
    assert switches(trace)[-1][1] == "engaged"  # still faulty: no hand-back
    assert_only_fallback_while_engaged(trace)
    assert_guarantees(trace)


def test_a_fallback_engaged_right_after_a_rejection_keeps_the_platforms_guarantees(tmp_path):
    """Every plan breaks a rule: after three cancelled adaptations the fallback engages right
    after a rejection, and no plan was ever accepted. Its plan was proved legitimate in every
    context before the run, and its records say so before its action goes out."""
    app = write_app(tmp_path / "app", when="stage_failures", after=3)
    trace = run_app(app, seed=1, duration=4, components={"plan": BreaksRules()})
    assert [what for _, what in switches(trace)] == ["engaged"]
    assert not [r for r in trace if r.get("legitimate") and r["plan"] != "f1"]
    events = [(r.get("plan"), key) for r in trace
              for key in ("planned", "rejected", "legitimate", "trusted", "executed") if r.get(key)]
    start = events.index(("f1", "legitimate"))
    assert events[start - 1][1] == "rejected"  # the last word on a plan before: a rejection
    assert events[start:start + 3] == [("f1", "legitimate"), ("f1", "trusted"), ("f1", "executed")]
    proved = next(r for r in trace if r.get("legitimate"))
    assert "proved legitimate in every context before the run" in proved["explanation"]
    assert_guarantees(trace)


def test_a_planner_that_overruns_its_budget_ends_in_fallback(tmp_path):
    app = write_app(tmp_path / "app", when="stage_failures", after=2)
    trace = run_app(app, seed=1, duration=6, components={"plan": Overruns()}, stage_budget=0.02)
    assert [what for _, what in switches(trace)] == ["engaged"]
    assert switches(trace)[0][0] <= 3 * PERIOD + 1e-9
    assert_only_fallback_while_engaged(trace)


# ---------------------------------------------------------------- a lost managed system


def test_a_lost_managed_system_engages_the_fallback_and_its_return_hands_back(tmp_path):
    # the robot goes silent from 4.0 to 8.0; its probe may stay silent for 1 s
    app = write_app(tmp_path / "app", when="managed_system_lost", dwell=1.0, staleness=1.0)
    trace = run_app(app, seed=1, duration=12, scenario={"silent": [[4.0, 8.0]]})
    # its last reading came at 3.5: lost at 4.5 (a deadline of its own, not a loop tick);
    # back with the reading at 8.0 (at once, not at the next tick), handed back a dwell later
    assert switches(trace) == [(4.5, "engaged"), (9.0, "released")]
    lost = [r for r in trace if "managed_system_lost" in str(r.get("explanation"))]
    assert lost[0]["time"] == 4.5 and "probe robot/sensors silent for 1 s" in lost[0]["explanation"]
    # offline, the fallback action cannot be delivered: it is retried until it is (at once
    # when the managed system is back; the release waits the dwell after that)
    f1 = [(r["time"], "executed" if r.get("executed") else "dropped")
          for r in trace if r.get("plan") == "f1" and ("executed" in r or "dropped" in r)]
    assert f1[0] == (4.5, "dropped") and f1[-1] == (8.0, "executed")
    assert_only_fallback_while_engaged(trace)
    assert_guarantees(trace)  # each delivery tried says the plan is legitimate first
    # nothing but the fallback's action was sent to the silent robot
    assert not [r for r in trace if r.get("executed") and 4.5 <= r["time"] < 8.0]


def test_managed_system_lost_that_nothing_could_report_is_refused_with_its_place(tmp_path):
    app = write_app(tmp_path / "app", when="managed_system_lost")  # local bus, no staleness
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated", seed=1, knowledge="memory"))
    message = str(caught.value)
    assert "app.yaml:" in message and "managed_system_lost can never fire over local" in message
    run = subprocess.run([sys.executable, "-m", "rasm.cli", "lint", str(app)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 1 and "managed_system_lost can never fire" in run.stdout, run


# ---------------------------------------------------------------- refused before it runs


def test_a_fallback_the_rules_do_not_admit_in_every_context_is_refused_at_start(tmp_path):
    app = write_app(tmp_path / "app", level=2)  # calm_when_fast breaks it when speed > 1
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated", seed=1, knowledge="memory")).build()
    message = str(caught.value)
    assert "app.yaml:" in message and "fallback actions are not legitimate" in message
    assert "calm_when_fast" in message and "speed ==" in message


@pytest.mark.slow
def test_rasm_run_and_verify_rules_refuse_such_a_fallback_with_the_place(tmp_path):
    app = write_app(tmp_path / "app", level=2)
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--clock", "simulated",
         "--duration", "2"], capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )
    assert run.returncode == 2, run.stdout + run.stderr
    assert "app.yaml:" in run.stderr and "Traceback" not in run.stderr
    verify = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "verify-rules", str(app)],
        capture_output=True, text=True, timeout=120,
    )
    assert verify.returncode == 1
    assert "fallback: NOT legitimate in every context: breaks calm_when_fast" in verify.stdout
    write_app(tmp_path / "good", level=0)
    verify = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "verify-rules", str(tmp_path / "good")],
        capture_output=True, text=True, timeout=120,
    )
    assert verify.returncode == 0, verify.stdout
    assert "fallback: legitimate in every context the rules admit: level == 0" in verify.stdout
    verify = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "verify-rules", str(app / "app.yaml"),
         "--format", "json"], capture_output=True, text=True, timeout=120,
    )
    assert verify.returncode == 1
    found = json.loads(verify.stdout)["fallback"]
    speed = found["context"]["speed"]  # z3's witness: any speed where calm_when_fast applies
    assert 1.0 < speed <= 10.0
    assert found == {
        "actions": {"level": 2}, "legitimate": False, "context": {"speed": speed},
        "broken": ["calm_when_fast"], "reason": f"breaks calm_when_fast where speed == {speed}",
    }


def test_a_fallback_for_an_unknown_effector_is_refused_at_its_line(tmp_path):
    app = write_app(tmp_path / "app")
    text = (app / "app.yaml").read_text().replace("{motor: {level: 0}}", "{wheel: {level: 0}}")
    (app / "app.yaml").write_text(text)
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated"))
    assert "fallback action for unknown effector 'wheel' (effectors: motor)" in str(caught.value)


@pytest.mark.slow
@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(windows=st.lists(
    st.tuples(st.integers(2, 24), st.integers(1, 6)).map(lambda w: (w[0] / 2, w[1] / 2)),
    min_size=1, max_size=3,
))
def test_while_a_veto_holds_nothing_but_the_fallback_acts(tmp_path_factory, windows):
    """For any schedule of veto violations: the fallback holds from the first violating record,
    only its actions go out until the release, and it never hands back within the dwell of a
    violation."""
    app = write_app(tmp_path_factory.mktemp("app"), when="veto", dwell=1.5)
    fast = [[start, start + length] for start, length in windows]
    trace = run_app(app, seed=1, duration=16, scenario={"fast": fast})
    assert_only_fallback_while_engaged(trace)
    assert_guarantees(trace)
    engaged, last_fast = False, None
    for record in trace:
        if record.get("fallback") == "engaged":
            engaged = True
        elif record.get("fallback") == "released":
            engaged = False
            assert last_fast is not None and record["time"] - last_fast >= 1.5
        if record.get("speed") == 2.0:
            last_fast = record["time"]
            # a violating record: the fallback holds by the end of that instant
            same_instant = [r for r in trace if r["time"] == record["time"]]
            assert engaged or any(r.get("fallback") == "engaged" for r in same_instant)


def test_a_fallback_value_that_does_not_fit_its_effector_field_is_refused(tmp_path):
    app = write_app(tmp_path / "app")
    text = (app / "app.yaml").read_text()
    text = text.replace("  motor:\n    topic: robot/motor\n",
                        "  motor:\n    topic: robot/motor\n    fields: {level: int}\n")
    (app / "app.yaml").write_text(text.replace("{motor: {level: 0}}", '{motor: {level: "low"}}'))
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated"))
    message = str(caught.value)
    assert "app.yaml:" in message and "the fallback action for motor: level:" in message
    assert "expected int, got str" in message


OUTCOMES = st.sampled_from(["idle", "executed", "dropped", "failed", "timeout", "cancelled",
                            "no_plan"])


@given(st.lists(OUTCOMES, max_size=40), st.integers(1, 4))
def test_the_stage_failures_trigger_follows_its_rule_for_any_run_of_iterations(outcomes, n):
    """The trigger holds from the n-th failed iteration since the last adaptation that reached
    Execute, until such an adaptation or n iterations in a row without a failure."""
    from rasm.platform.fallback import FailedIterations
    from rasm.platform.protocols import LoopStats

    stats, counter = LoopStats(), FailedIterations(n)
    failures = clean = 0
    holding = False
    for outcome in outcomes:
        stats.iterations += 1
        if outcome != "idle":
            stats.anomalies += 1
        if outcome in ("executed", "dropped"):
            setattr(stats, outcome, getattr(stats, outcome) + 1)
        elif outcome == "failed":
            stats.failed_stages["plan"] += 1
        elif outcome == "timeout":
            stats.timeouts["plan"] += 1
        elif outcome == "cancelled":
            stats.cancelled += 1
        counter.update(stats)
        # the model
        if outcome in ("failed", "timeout", "cancelled", "no_plan"):
            failures, clean = failures + 1, 0
        else:
            clean += 1
            if outcome in ("executed", "dropped") or (holding and clean >= n):
                failures = 0
        holding = failures >= n
        assert counter.holds == holding, (outcome, failures, clean)


# ---------------------------------------------------------------- a violation inside a batch

BURST = '''

class BurstSimulator(GuardedSimulator):
    """At the scenario's burst times, one step publishes a fast reading and then a slow one:
    two messages that reach the loop together, as a transport delivers a batch."""

    def __init__(self, scenario=None, seed=0):
        super().__init__(scenario, seed)
        self.bursts = [float(t) for t in (scenario or {}).get("bursts", [])]

    def step(self, time, dt):
        readings = super().step(time, dt)
        if any(abs(time - t) < dt / 2 for t in self.bursts):
            return {"robot/sensors": {"speed": 2.0, "x": 1.0}, "robot/again": {"speed": 0.5}}
        return readings
'''


def write_burst_app(folder):
    app = write_app(folder, when="veto", dwell=1.0)
    (app / "components.py").write_text((app / "components.py").read_text() + BURST)
    text = (app / "app.yaml").read_text().replace(
        "simulator: components:GuardedSimulator", "simulator: components:BurstSimulator"
    ).replace(
        "effectors:",
        "  - topic: robot/again\n    signals:\n      speed: {type: float, min: 0, max: 10}\n"
        "effectors:",
    )
    (app / "app.yaml").write_text(text)
    return app


def test_a_veto_violated_then_satisfied_in_one_batch_engages_the_fallback(tmp_path):
    app = write_burst_app(tmp_path / "app")
    bursts = [2.0, 4.0, 6.0]
    trace = run_app(app, seed=1, duration=9, scenario={"bursts": bursts})
    # each burst: the fast reading violates `slow`, the slow one right after it satisfies it
    violated = [r["time"] for r in trace if r.get("speed") == 2.0]
    assert violated == bursts
    # every violation engaged the fallback at its instant, with the violation as the reason
    engaged = [r for r in trace if r.get("fallback") == "engaged"]
    assert [r["time"] for r in engaged] == bursts
    assert all("veto property slow violated at t=" in r["explanation"] for r in engaged)
    assert [what for _, what in switches(trace)] == ["engaged", "released"] * 3
    assert_only_fallback_while_engaged(trace)
    # from the violating record to the engagement nothing but the fallback acted
    for burst in bursts:
        at_burst = [r for r in trace if r["time"] == burst]
        fast = next(k for k, r in enumerate(at_burst) if r.get("speed") == 2.0)
        engaged_at = next(k for k, r in enumerate(at_burst) if r.get("fallback") == "engaged")
        between = at_burst[fast:engaged_at]
        assert not any(r.get("executed") for r in between), between


def test_between_a_violation_and_the_engagement_the_loop_s_actions_are_held(tmp_path):
    from rasm.platform.components import Action
    from rasm.properties import Verdict

    app = write_app(tmp_path / "app", when="veto")
    platform = Platform(app, RunOptions(clock="simulated", seed=1, knowledge="memory"))
    platform.start()
    try:
        side = platform.managing
        switch, hold = side.fallback_switch, side.fallback_hold
        loop_action = Action("motor", {"level": 1}, "p1")
        assert switch.state == "nominal" and hold.holds(loop_action) is None
        # a violation and, in the same batch, the verdict that clears it: the switch has not
        # read its triggers yet (that is the next job), yet it holds the loop's actions
        side.trustworthiness_checker.take(Verdict("slow", 3, 1.5, False))
        side.trustworthiness_checker.take(Verdict("slow", 4, 1.5, True))
        assert switch.state == "nominal"
        assert "veto property slow violated at t=1.5" in hold.holds(loop_action)
        assert hold.holds(Action("motor", {"level": 0}, "f1", "fallback")) is None
        platform.scheduler.run_until(platform.clock.time)  # the jobs submitted: the evaluation
        assert switch.state == "fallback" and switch.engagements == 1
        assert "veto property slow violated at t=1.5" in switch.trigger_reason()
    finally:
        platform.stop()



def test_a_future_veto_property_engages_the_fallback_as_soon_as_its_verdict_is_decided(
    tmp_path,
):
    """``always[0, 1] slow and eventually[0, 20] flare`` (a flare at 3.0 s and 8.0 s): at the
    first fast record, 5.0 s, the records from 4.0 s on are false — their always fails —
    though their eventually still waits for the flare at 8.0 s. The fallback engages at 5.0 s,
    not when the eventually is decided."""
    app = write_app(tmp_path / "app", when="veto", dwell=1.0, veto=("settles",))
    (app / "properties" / "robot.rv").write_text(
        "input speed: float\n"
        "input x: float\n"
        "property settles:\n"
        "    (always[0, 1] (speed <= 1.0)) and (eventually[0, 20] (x > 1e300))\n"
    )
    trace = run_app(app, seed=1, duration=12,
                    scenario={"fast": [[5.0, 9.0]], "overflow_at": [3.0, 8.0]})
    # no verdict until the first flare (3.0 s): engaged at the first tick, released after
    # the dwell once verdicts vouch, engaged again at the first fast record
    assert switches(trace)[:3] == [(0.5, "engaged"), (4.0, "released"), (5.0, "engaged")]
    engaged = next(r for r in trace if r.get("fallback") == "engaged" and r["time"] == 5.0)
    assert "veto property settles violated at t=4" in engaged["explanation"]
    assert_only_fallback_while_engaged(trace)
