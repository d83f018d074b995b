"""The Trustworthiness Checker: the only path to an effector, and the online monitors' verdicts."""

from __future__ import annotations

from hypothesis import given, settings

from rasm import Action, Platform, RunOptions
from rasm.cli import main
from rasm.platform.manifest import Effector, load_manifest
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.properties import compile_properties
from rasm.properties.outcome import Untested
from rasm.properties.vacuity import Vacuity

from .conftest import HOTBOX
from .scripted import Scripted
from .test_trustworthiness_manager import STEPS


def checker(monitors):
    return TrustworthinessChecker(
        monitors=monitors, effectors={}, send=lambda effector, action: None, mode_of=lambda: None
    )


def test_checker_sends_only_applicable_actions_to_known_effectors():
    sent = []
    mode = {"now": "docked"}
    tc = TrustworthinessChecker(
        monitors=[],
        effectors={"wheels": Effector("wheels", "robot/wheels", ("navigate",))},
        send=lambda effector, action: sent.append((effector.name, action.payload)),
        mode_of=lambda: mode["now"],
    )
    assert not tc.register_action(Action("wheels", {"v": 1})).sent  # not started yet
    tc.send("configure")
    outcome = tc.register_action(Action("wheels", {"v": 1}))
    assert not outcome.sent and "mode 'docked'" in outcome.why
    outcome = tc.register_action(Action("laser", {"on": True}))
    assert not outcome.sent and "unknown effector" in outcome.why
    mode["now"] = "navigate"
    assert tc.register_action(Action("wheels", {"v": 2})).sent
    assert sent == [("wheels", {"v": 2})]
    assert "monitoring" in tc.configuration  # the chart went checking_action -> monitoring


class _Faulty:
    properties = ["faulty"]

    def step(self, time, record):
        raise RuntimeError("broken monitor")

    def finish(self):
        return []

    def missing(self, name):
        return ()


def test_checker_hands_verdicts_to_the_observers_listed_now_and_a_faulty_monitor_is_in_error():

    monitor = compile_properties("input x: float\nproperty low: always (x < 1)\n")
    called: list = []
    observers: list = [called.append]
    tc = TrustworthinessChecker(
        monitors=[_Faulty(), monitor],
        effectors={},
        send=lambda effector, action: None,
        mode_of=lambda: None,
        observers=observers,
    )
    first = tc.observe(0.0, {"x": 0.5})
    # the faulty monitor's properties are in error for the record; the others are judged
    assert [(v.property, v.value) for v in first] == [("faulty", False), ("low", True)]
    assert "RuntimeError: broken monitor" in first[0].error and first[1].error is None
    assert tc.monitor_failures == 1
    seen: list = []
    observers.append(seen.append)  # added during the run: called from the next record on
    second = tc.observe(1.0, {"x": 2.0})
    assert seen == second and called == first + second
    assert {name: v.value for name, v in tc.latest.items()} == {"faulty": False, "low": False}
    assert tc.outcomes["low"].state == "violated" and tc.outcomes["low"].violations == 1
    assert tc.outcomes["faulty"].state == "error" and tc.outcomes["faulty"].errors == 2
    assert tc.monitor_failures == 2


def test_platform_verdict_observers_added_while_running_see_the_live_verdicts(hotbox):
    platform = Platform(hotbox, RunOptions(clock="simulated", knowledge="memory"))
    seen: list = []
    platform.start()
    platform.on_verdict.append(seen.append)
    try:
        platform.scheduler.run_until(platform.clock.time + 2.0)
    finally:
        platform.stop()
    assert {v.property for v in seen} >= {"temperature_band", "stage_order"}
    assert all(v.value is True for v in seen)


@settings(max_examples=100, deadline=None)
@given(steps=STEPS)
def test_the_checker_counts_every_record_a_monitor_failed_on_as_an_error(steps):
    tc = checker([Scripted(steps)])
    for time, _ in enumerate(steps):
        tc.observe(float(time), {})
    outcome = tc.outcomes["guard"]
    values = [v for what in steps if what != "nothing"
              for v in (what if isinstance(what, list) else [what])]
    assert outcome.errors == steps.count("raise") == tc.monitor_failures
    assert outcome.violations == values.count(False)
    assert outcome.judged == len(values)
    if "raise" in steps:
        assert outcome.state in ("violated", "error")
    if not outcome.judged:
        assert outcome.state == "not judged"



def test_the_checker_names_the_antecedents_that_never_held_at_the_end():
    monitor = compile_properties(
        "input x: float\nevent alarm\nevent reset\n"
        "property calm: always (alarm -> x < 1)\nproperty back: always (reset -> x < 2)\n"
    )
    tc = TrustworthinessChecker(
        monitors=[monitor], effectors={}, send=lambda effector, action: None,
        mode_of=lambda: None, vacuity=[Vacuity(monitor.spec)],
    )
    tc.observe(0.0, {"x": 0.5})
    tc.observe(1.0, {"x": 0.5, "reset": True})
    tc.finish()
    assert tc.outcomes["calm"].vacuous == (Untested("alarm", event=True),)
    assert tc.outcomes["calm"].word == "satisfied (vacuously: alarm never happened)"
    assert tc.outcomes["back"].vacuous == () and tc.outcomes["back"].word == "satisfied"


class _BrokenWatch:
    spec = None

    def step(self, time, values):
        raise RuntimeError("broken watch")

    def finish(self):
        raise AssertionError("a watch that raised is not stepped again")

    def vacuous(self, name):
        return (Untested("alarm", event=True),)


def test_a_failing_antecedent_watch_never_stops_the_checker_and_leaves_them_vacuous(caplog):
    monitor = compile_properties("input x: float\nevent alarm\nproperty calm: always (alarm -> "
                                 "x < 1)\n")
    tc = TrustworthinessChecker(
        monitors=[monitor], effectors={}, send=lambda effector, action: None,
        mode_of=lambda: None, vacuity=[_BrokenWatch()],
    )
    assert [v.value for v in tc.observe(0.0, {"x": 0.5, "alarm": True})] == [True]
    assert [v.value for v in tc.observe(1.0, {"x": 0.5})] == [True]
    tc.finish()
    assert "broken watch" in caplog.text
    # it cannot vouch that the alarm was put to the test: the property says vacuously
    assert tc.outcomes["calm"].word == "satisfied (vacuously: alarm never happened)"


def test_a_run_without_an_anomaly_says_its_timeliness_was_never_put_to_the_test(
    tmp_path, capsys, monkeypatch
):
    # the Hotbox's lid first opens at 8 s: in 5 s nothing happens that the loop must answer
    monkeypatch.chdir(tmp_path)
    code = main(["run", str(HOTBOX), "--clock", "simulated", "--seed", "1", "--duration", "5"])
    out = capsys.readouterr().out
    assert code == 0  # vacuously satisfied still passes
    assert "timely_response: satisfied (vacuously: anomaly never happened)" in out
    assert "boost_while_open" in out
    summary = Platform(load_manifest(HOTBOX), RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
    )).run(5)
    listed = {p["name"]: p["vacuous"] for p in summary.properties()}
    assert listed["timely_response"] == ["anomaly"] and listed["prompt_planning"] == ["anomaly"]
    assert listed["stage_order"] == []  # the stages did move: it was put to the test
