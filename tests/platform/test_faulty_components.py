"""Faults in user code never let an unchecked action through, and never stop the loop."""

from __future__ import annotations

import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.platform.components import Action, Anomaly, Plan
from rasm.rules import RuleSet

from .conftest import HOTBOX, read_trace

GOOD = {"mode": "boost", "setpoint": 38.5, "power_limit": 100.0}
BREAKS_RULES = [
    {"mode": "boost", "setpoint": 45.0, "power_limit": 100.0},  # safe_setpoint
    {"mode": "normal", "setpoint": 37.0, "power_limit": 95.0},  # normal_power
    {"mode": "boost", "setpoint": 38.0, "power_limit": 150.0},  # heater_rating
    {"mode": "turbo", "setpoint": 38.0, "power_limit": 50.0},  # not an enum value
    {"mode": "boost", "setpoint": "hot", "power_limit": 50.0},  # wrong type
    {"setpoint": 38.0},  # missing values
]
BEHAVIOURS = st.sampled_from(["ok", "raise", "garbage", "breaks_rules", "slow", "none"])


class Scripted:
    """Planner/executor whose behaviour on each call is drawn by hypothesis."""

    def __init__(self, plan_script, execute_script, analyse_script):
        self.plan_script = list(plan_script)
        self.execute_script = list(execute_script)
        self.analyse_script = list(analyse_script)
        self.calls = 0

    @staticmethod
    def _next(script):
        return script.pop(0) if script else "ok"

    def analyse(self, ctx):
        what = self._next(self.analyse_script)
        if what == "raise":
            raise RuntimeError("analysis crashed")
        if what == "garbage":
            return 42
        return {"reason": "scripted", "want": "boost"}  # an anomaly every iteration

    def plan(self, ctx):
        self.calls += 1
        what = self._next(self.plan_script)
        if what == "raise":
            raise ZeroDivisionError("planner bug")
        if what == "garbage":
            return ["not", "a", "plan"]
        if what == "breaks_rules":
            return dict(BREAKS_RULES[self.calls % len(BREAKS_RULES)])
        if what == "slow":
            threading.Event().wait(0.2)  # overruns the 0.05 s budget: simulates a slow planner
            return dict(GOOD)
        if what == "none":
            return None
        return dict(GOOD)

    def execute(self, ctx):
        what = self._next(self.execute_script)
        if what == "raise":
            raise RuntimeError("executor crashed")
        if what == "garbage":
            return "heater: on"
        if what == "breaks_rules":  # an action for an effector that does not exist
            return Action("laser", {"power": 1})
        return Action("heater", dict(ctx.plan.values))


@pytest.mark.slow
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    plan=st.lists(BEHAVIOURS, max_size=12),
    execute=st.lists(BEHAVIOURS, max_size=8),
    analyse=st.lists(st.sampled_from(["ok", "raise", "garbage"]), max_size=6),
)
def test_faulty_components_never_get_an_unchecked_action_executed(
    plan, execute, analyse, tmp_path_factory
):
    from rasm.platform.manifest import load_manifest

    manifest = load_manifest(HOTBOX)
    manifest.stage_budget = 0.05
    scripted = Scripted(plan, execute, analyse)
    trace_file = tmp_path_factory.mktemp("faulty") / "trace.jsonl"
    platform = Platform(
        manifest,
        RunOptions(
            clock="simulated",
            seed=3,
            trace=trace_file,
            knowledge="memory",
            components={"analyse": scripted, "plan": scripted, "execute": scripted},
        ),
    )
    applied = []
    platform.build()
    simulator = platform.assembly.managed_system.simulator
    original = simulator.apply
    simulator.apply = lambda eff, payload, t: (
        applied.append((eff, payload)),
        original(eff, payload, t),
    )
    summary = platform.run(8.0)
    trace = read_trace(trace_file)

    # the loop kept running: one iteration per period, whatever failed
    assert summary.stats.iterations == int(8.0 / manifest.period)
    rules = RuleSet.load(HOTBOX / "rules" / "hotbox.yaml")
    legitimate = {r["plan"] for r in trace if r.get("legitimate")}
    executed = [r["plan"] for r in trace if r.get("executed")]
    plans = {r["plan"]: r for r in trace if r.get("planned")}
    for plan_id in executed:
        assert plan_id in legitimate, f"{plan_id} executed without passing Legitimate"
        values = {k: plans[plan_id][k] for k in ("mode", "setpoint", "power_limit")}
        assert rules.evaluate(values, {"temperature": 37.0}).accepted
    # what reached the effector is exactly what was executed, and every payload obeys the rules
    assert len(applied) == len(executed)
    for effector, payload in applied:
        assert effector == "heater"
        values = {k: payload[k] for k in ("mode", "setpoint", "power_limit")}
        assert rules.evaluate(values, {"temperature": 37.0}).accepted
    for r in trace:
        if r.get("rejected"):
            assert r["plan"] not in executed and r["broken_rules"]


class _BadStr(Exception):
    """An exception whose message cannot be made (its __str__ reads an attribute never set)."""

    def __str__(self):
        return self.message


class _Odd:
    """An anomaly every iteration; ``stage`` returns ``value`` (or raises it) instead."""

    def __init__(self, stage, value):
        self.stage, self.value = stage, value

    def monitor(self, ctx):
        return self._give("monitor", None)

    def _give(self, stage, normal):
        if stage != self.stage:
            return normal
        if isinstance(self.value, BaseException):
            raise self.value
        return self.value

    def analyse(self, ctx):
        return self._give("analyse", {"reason": "scripted", "want": "boost"})

    def plan(self, ctx):
        return self._give("plan", dict(GOOD))

    def execute(self, ctx):
        return self._give("execute", Action("heater", dict(ctx.plan.values)))


def _run_odd(tmp_path, stage, value, seconds=3.0):
    from rasm.platform.manifest import load_manifest

    odd = _Odd(stage, value)
    platform = Platform(
        load_manifest(HOTBOX),
        RunOptions(
            clock="simulated",
            seed=3,
            trace=tmp_path / "trace.jsonl",
            knowledge="memory",
            state_dir=tmp_path,
            components={"monitor": odd, "analyse": odd, "plan": odd, "execute": odd},
        ),
    )
    applied = []
    platform.build()
    simulator = platform.assembly.managed_system.simulator
    simulator.apply = lambda eff, payload, t: applied.append((eff, payload))
    summary = platform.run(seconds)
    return summary, read_trace(tmp_path / "trace.jsonl"), applied


@pytest.mark.parametrize(
    ("stage", "value", "why"),
    [
        ("plan", Plan("abc"), "plan: Plan values must be a dict with str keys, not str"),
        ("plan", Plan(None), "plan: Plan values must be a dict with str keys, not NoneType"),
        ("analyse", Anomaly("x", "no dict"), "analyse: Anomaly data must be a dict, not str"),
        (
            "execute",
            Action("heater", "boost"),
            "execute: the payload for 'heater' must be a dict, not str",
        ),
        ("plan", SystemExit(3), "SystemExit: 3"),
        ("plan", _BadStr(), "_BadStr: <str() of the exception failed>"),
        (  # derived signals named like the loop's own keys forged its events (and "time")
            "monitor",
            {"executed": True, "time": -5.0},
            "monitor returned 'executed', a key the loop writes itself in the trace (anomaly, ",
        ),
        ("execute", SystemExit(), "SystemExit: "),
        (  # a flood: refused whole (a partial adaptation would be as bad), loop.max_actions = 16
            "execute",
            [Action("heater", dict(GOOD))] * 17,
            "execute returned 17 actions, more than loop.max_actions (16): none was sent",
        ),
    ],
)
def test_odd_results_and_sys_exit_fail_the_stage_and_the_loop_goes_on(tmp_path, stage, value, why):
    summary, trace, applied = _run_odd(tmp_path, stage, value)
    assert summary.stats.iterations == int(3.0 / 0.5)  # every iteration ran
    assert summary.stats.failed_stages[stage] == summary.stats.iterations
    assert applied == []
    failures = [r["explanation"] for r in trace if "stage failed" in r.get("explanation", "")]
    assert failures and failures[0].startswith(f"{stage} stage failed: {why}")


def test_max_actions_is_a_manifest_setting(tmp_path):
    from rasm.platform.manifest import load_manifest

    manifest = load_manifest(HOTBOX)
    manifest.max_actions = 20
    odd = _Odd("execute", [Action("heater", dict(GOOD))] * 17)
    platform = Platform(manifest, RunOptions(
        clock="simulated",
        seed=3,
        knowledge="memory",
        state_dir=tmp_path,
        components={"monitor": odd, "analyse": odd, "plan": odd, "execute": odd},
    ))
    summary = platform.run(1.0)
    assert summary.stats.executed == summary.stats.iterations > 0
    assert not summary.stats.failed_stages


def test_non_text_reason_or_explanation_is_written_as_text(tmp_path):
    reasonless = Anomaly(reason=404)
    summary, trace, applied = _run_odd(tmp_path, "analyse", reasonless)
    assert summary.stats.executed == summary.stats.iterations
    assert {r["explanation"] for r in trace if r.get("anomaly")} == {"404"}
    odd_plan = Plan(dict(GOOD), explanation=["boost"])
    summary, trace, applied = _run_odd(tmp_path, "plan", odd_plan)
    assert summary.stats.executed == summary.stats.iterations
    assert {r["explanation"] for r in trace if r.get("planned")} == {"['boost']"}


def test_an_action_that_breaks_the_rules_is_dropped_even_when_its_plan_was_legitimate(tmp_path):
    # the plan (GOOD) passes Legitimate, but Execute sends other values than the plan's
    rogue = {"heater": {"mode": "boost", "setpoint": 38.5, "power_limit": 150.0}}
    summary, trace, applied = _run_odd(tmp_path, "execute", rogue)
    assert applied == []
    assert summary.stats.executed == 0 and summary.stats.dropped == summary.stats.iterations
    dropped = [r["explanation"] for r in trace if r.get("dropped")]
    assert dropped[0].startswith("rules do not accept the action: heater_rating:")


def test_a_faulty_simulator_is_logged_and_the_run_goes_on(tmp_path, caplog):
    from rasm.platform.manifest import load_manifest

    platform = Platform(
        load_manifest(HOTBOX), RunOptions(clock="simulated", seed=3, knowledge="memory",
                                          state_dir=tmp_path)
    )
    platform.build()
    simulator = platform.assembly.managed_system.simulator
    step = simulator.step
    answers = iter([SystemExit(4), "garbage", {5: {}}, {"hotbox/sensors": {"t": float("nan")}}])

    def faulty_step(time, dt):
        answer = next(answers, None)
        if isinstance(answer, BaseException):
            raise answer
        return step(time, dt) if answer is None else answer

    def faulty_apply(effector, payload, time):
        raise SystemExit("apply crashed")

    simulator.step = faulty_step
    simulator.apply = faulty_apply
    summary = platform.run(20.0)  # sys.exit() in the simulator used to end the run at once
    assert summary.stats.iterations == int(20.0 / 0.5) and summary.stats.executed >= 1
    errors = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert errors[:4] == [
        "the simulator's step failed: SystemExit: 4",
        "the simulator's step must return {topic: payload} or None, not str",
        "the simulator's reading on 5 was not published: topic must be a string, got int",
        "the simulator's reading on 'hotbox/sensors' was not published: "
        "payload['t']: nan is not a finite number (JSON has no NaN/inf)",
    ]
    assert "the simulator's apply('heater') failed: SystemExit: apply crashed" in errors
