"""The checker fails closed, end to end: a property that never saw its signal is not judged and
fails the run; two readings of 1e308 that overflow a window sum never let an action through
that the checker cannot vouch for, on the simulated clock and over a real mosquitto.

The overflow tests hold whether the monitor raises on the overflowed sum (every property of its
file is then in error until it works again) or saturates it (the sum property is violated, the
others are judged as usual): they assert what both must give.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading

import paho.mqtt.publish as paho_publish
import pytest

from rasm import Platform, RunOptions
from rasm.errors import SourceErrors
from rasm.testing import PropertyViolation, assert_properties, run_app
from rasm.testing.servers import start_mosquitto

from .guarded import write_guarded_app

PLATFORM_PROPERTIES = (
    "stage_order", "execute_only_legitimate_plans", "rejected_plans_stay_rejected", "loop_alive",
    "stage_budget",
)


# ---------------------------------------------------------------- a signal that never arrives

HEADING = "input heading: float\n"
STEADY = "\nproperty steady:\n    always (heading <= 90)\n"


def test_a_property_whose_signal_never_arrives_is_not_judged_and_fails(tmp_path):
    """The manifest and the property say ``heading``; the robot never publishes it (its driver
    names it differently). No static check can see that: the run must."""
    app = write_guarded_app(
        tmp_path / "app", signals={"heading": "float"}, inputs=HEADING, extra=STEADY, every=8
    )
    trace = run_app(app, seed=1, duration=5)
    summary = trace.summary
    assert summary.verdicts["steady"] == "not judged"
    assert summary.outcomes["steady"].missing == ("heading",)
    assert summary.verdicts["slow"] == "satisfied"  # the others are judged as usual
    assert not summary.ok
    assert {"name": "steady", "verdict": "not judged", "violations": 0, "judged": 0,
            "inconclusive": 0, "errors": 0, "first_error": None,
            "missing": ["heading"], "vacuous": []} in summary.properties()
    with pytest.raises(PropertyViolation) as caught:
        assert_properties(app / "properties" / "robot.rv", trace)
    assert str(caught.value).startswith("not judged: steady (no value for heading)")
    assert "steady: NOT JUDGED: no value for heading in any record" in str(caught.value)
    assert_properties(app / "properties" / "robot.rv", trace, only=["slow"])


def test_rasm_run_says_not_judged_names_the_signal_and_exits_1(tmp_path):
    app = write_guarded_app(
        tmp_path / "app", signals={"heading": "float"}, inputs=HEADING, extra=STEADY, every=8
    )
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--clock", "simulated",
         "--duration", "3", "--seed", "1"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )
    assert run.returncode == 1, run.stdout + run.stderr
    row = next(line for line in run.stdout.splitlines() if " steady " in line)
    assert "not judged" in row and "satisfied" not in row
    assert "1 of 11 properties not satisfied: steady (not judged)" in run.stdout
    assert "  steady: not judged: no value for heading\n" in run.stdout
    assert "Traceback" not in run.stderr


def test_a_veto_property_that_is_never_judged_lets_no_action_through(tmp_path):
    app = write_guarded_app(
        tmp_path / "app", signals={"heading": "float"}, inputs=HEADING, extra=STEADY,
        veto=("steady",),
    )
    trace = run_app(app, seed=1, duration=5)
    assert trace.when("executed") == []
    dropped = [r["explanation"] for r in trace if r.get("dropped")]
    assert dropped and set(dropped) == {
        "veto property steady not judged yet: no value for heading"
    }


def test_a_veto_property_that_names_no_property_is_refused_at_start_up(tmp_path):
    app = write_guarded_app(tmp_path / "app", veto=("slow", "slwo"))
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated")).build()
    message = str(caught.value)
    assert "veto property 'slwo' is not a property of this app" in message
    assert f"{app / 'app.yaml'}:" in message  # placed in the manifest
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--clock", "simulated",
         "--duration", "1"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )
    assert run.returncode == 2 and "veto property 'slwo' is not a property" in run.stderr
    assert "Traceback" not in run.stderr


# ---------------------------------------------------------------- the overflow attack


class Watcher:
    """Every verdict and record of a run, in the order the loop made them."""

    def __init__(self, platform: Platform) -> None:
        self.events: list[tuple] = []
        self.lock = threading.Lock()
        self.reached = threading.Condition(self.lock)
        self.time = 0.0
        platform.on_verdict.append(self.verdict)
        platform.on_record.append(self.record)

    def verdict(self, verdict) -> None:
        with self.lock:
            self.events.append(("verdict", verdict))

    def record(self, time, record) -> None:
        with self.lock:
            self.events.append(("record", time, dict(record)))
            self.time = time
            self.reached.notify_all()

    def wait_until(self, time: float, timeout: float = 30.0) -> None:
        with self.reached:
            assert self.reached.wait_for(lambda: self.time >= time, timeout), self.time

    def verdicts(self, name: str) -> list:
        return [e[1] for e in self.events if e[0] == "verdict" and e[1].property == name]

    def while_fast(self) -> list[dict]:
        """The executed and dropped records of the loop while the latest speed it had stored
        was over the limit."""
        speed, out = 0.0, []
        for event in self.events:
            if event[0] == "record":
                speed = event[2].get("speed", speed)
                if speed > 1.0 and (event[2].get("executed") or event[2].get("dropped")):
                    out.append(event[2])
        return out

    def decisions(self, veto: str) -> list[tuple[float, dict, object]]:
        """``(time, record, the veto property's latest verdict when the loop decided)`` for
        every trusted, executed or dropped record. A record's own verdicts reach the observers
        before the record does, so the decision saw the verdicts up to the record before."""
        latest = before = None
        out = []
        for event in self.events:
            if event[0] == "verdict":
                if event[1].property == veto:
                    latest = event[1]
                continue
            _, time, record = event
            if record.get("trusted") or record.get("executed") or record.get("dropped"):
                out.append((time, record, before))
            before = latest
        return out


def _vouched(verdict) -> bool:
    return verdict is not None and verdict.value is True and verdict.error is None


def _check_no_action_passed_unvouched(watcher: Watcher) -> None:
    for time, record, verdict in watcher.decisions("slow"):
        if record.get("trusted") or record.get("executed"):
            assert _vouched(verdict), (time, record, verdict)


def _simulated_run(tmp_path, scenario):
    app = write_guarded_app(tmp_path / "app")
    platform = Platform(app, RunOptions(clock="simulated", seed=1, scenario=scenario))
    watcher = Watcher(platform)
    summary = platform.run(25.0)
    return summary, watcher


def test_the_overflow_attack_on_the_simulated_clock_never_lets_an_unvouched_action_through(
    tmp_path,
):
    """The readings arrive just before the robot gets fast: a checker blind from then on would
    let through the actions the veto stops in the same run without them."""
    fast = {"fast": [[10.0, 14.0]]}
    clean, clean_watch = _simulated_run(tmp_path / "clean", fast)
    attacked, watch = _simulated_run(tmp_path / "attacked", {**fast, "overflow_at": [8.0, 8.5]})

    # the readings are finite floats of a signal without a range: Telegraf stores them
    overflowing = [e for e in watch.events if e[0] == "record" and e[2].get("x") == 1e308]
    assert [e[1] for e in overflowing] == [8.0, 8.5]

    # the actions the veto stops without the overflow are still stopped with it
    vetoed = {
        time for time, record, _ in clean_watch.decisions("slow")
        if record.get("dropped") and "veto property slow violated" in record["explanation"]
    }
    assert vetoed and min(vetoed) >= 10.0 and max(vetoed) <= 14.0
    executed = {time for time, record, _ in watch.decisions("slow") if record.get("executed")}
    assert not vetoed & executed
    # ... and no action passes while the checker cannot vouch for the veto property
    _check_no_action_passed_unvouched(watch)
    _check_no_action_passed_unvouched(clean_watch)

    # the overflowed property is not called satisfied; the clean run's is
    assert clean.verdicts["budget"] == "satisfied"
    assert attacked.verdicts["budget"] in ("violated", "error")
    assert not attacked.ok
    def judged_every_record(name: str) -> None:
        # both runs have the same warm-up (the records before the property's signals arrived)
        warm_up = clean.records - clean.outcomes[name].judged
        assert attacked.outcomes[name].judged == attacked.records - warm_up, name

    # the platform's own properties (another file) are judged on every record, without error
    for name in PLATFORM_PROPERTIES:
        judged_every_record(name)
        assert attacked.outcomes[name].errors == 0, name
        during = [v for v in watch.verdicts(name) if 8.5 <= v.time <= 13.5]
        assert during and all(v.error is None for v in during), name
    # the veto property is never skipped: every record gives it a verdict, or an error
    judged_every_record("slow")

    # the monitor recovers once the readings have left the 5 s window (the loop records of
    # t=9, before the reading of 1.0 at t=9, still held 1e308) and the robot is slow again
    for name in ("budget", "slow"):
        after = [v for v in watch.verdicts(name) if v.time >= 15.0]
        assert after and all(v.value is True and v.error is None for v in after), name
    assert any(time >= 15.0 for time in executed)


@pytest.mark.slow
def test_the_overflow_attack_over_mqtt_never_lets_an_unvouched_action_through(tmp_path):
    """Two unauthenticated probe messages from a foreign publisher, on the wall clock, just
    before the robot gets fast."""
    broker = start_mosquitto(tmp_path)
    try:
        app = write_guarded_app(tmp_path / "app", period=0.1, window="1s")
        platform = Platform(
            app, RunOptions(transport=broker.url, scenario={"fast": [[1.5, 2.5]]}, seed=1)
        )
        watcher = Watcher(platform)
        result: dict = {}
        runner = threading.Thread(target=lambda: result.update(summary=platform.run(5.0)))
        runner.start()
        try:
            watcher.wait_until(1.0)
            for _ in range(2):
                paho_publish.single(
                    "robot/sensors", json.dumps({"x": 1e308}), qos=1,
                    hostname=broker.host, port=broker.port,
                )
        finally:
            runner.join(timeout=60)
        assert not runner.is_alive()
    finally:
        broker.stop()
    summary = result["summary"]

    attack = [e[1] for e in watcher.events if e[0] == "record" and e[2].get("x") == 1e308]
    assert len(attack) == 2, "both readings reach the knowledge (a float without a range)"
    # the veto stopped the actions planned while the robot was fast, as far as the loop knew
    # (violated, or in error while the monitor could not tell): none passed
    while_fast = watcher.while_fast()
    assert any(
        record.get("dropped") and "veto property slow" in record["explanation"]
        for record in while_fast
    )
    assert not [record for record in while_fast if record.get("executed")]
    _check_no_action_passed_unvouched(watcher)
    assert summary.verdicts["budget"] in ("violated", "error")
    for name in PLATFORM_PROPERTIES:
        during = [v for v in watcher.verdicts(name) if attack[0] <= v.time <= attack[-1] + 1.0]
        assert during and all(v.error is None for v in during), name
    # recovered: the readings left the 1 s window, the checker vouches again, actions pass
    settled = max(attack[-1] + 1.5, 3.0)
    for name in ("budget", "slow"):
        after = [v for v in watcher.verdicts(name) if v.time >= settled]
        assert after and all(v.value is True and v.error is None for v in after), name
    assert any(
        record.get("executed") and time >= settled for time, record, _ in watcher.decisions("slow")
    )
