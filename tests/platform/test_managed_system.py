"""The simulated managed system: stepped every period on the loop's clock, its readings published,
the actions on its effector topics applied; a failing simulator is logged, never fatal."""

from __future__ import annotations

import logging

import pytest
from sismic.clock import SimulatedClock

from rasm.comm import LocalTransport
from rasm.logs import RepeatedLogs
from rasm.platform.communication_manager import CommunicationManager
from rasm.platform.managed_system import ManagedSystem
from rasm.platform.manifest import Effector
from rasm.platform.scheduler import Scheduler


class Box:
    """A simulator that counts its steps, fails when told, and keeps the actions it got."""

    def __init__(self, fail_from: float = float("inf")) -> None:
        self.fail_from = fail_from
        self.applied: list[tuple[str, dict, float]] = []

    def step(self, time: float, dt: float):
        if time >= self.fail_from:
            raise RuntimeError("sensor unplugged")
        return {"box/sensors": {"time_seen": time, "dt": dt}}

    def apply(self, effector: str, action: dict, time: float) -> None:
        self.applied.append((effector, action, time))


def started(box: Box, started_at: float = 10.0):
    clock = SimulatedClock()
    clock.time = started_at
    scheduler = Scheduler(clock)
    cm = CommunicationManager(LocalTransport(), clock=clock)
    cm.send("configure")
    readings: list[dict] = []
    cm.subscribe("box/sensors", lambda message: readings.append(message.payload))
    managed = ManagedSystem(
        box,
        period=0.5,
        effectors={"heater": Effector("heater", "box/heater")},
        logs=RepeatedLogs(),
    )
    managed.start(cm, scheduler, started_at=started_at, gate=lambda apply, topic: apply)
    return managed, cm, scheduler, readings


def test_readings_go_out_every_period_and_actions_are_applied_at_the_worlds_time() -> None:
    box = Box()
    _, cm, scheduler, readings = started(box)
    scheduler.run_until(11.0)
    # the simulated world's own time starts at 0 when the platform starts
    assert readings == [{"time_seen": t, "dt": 0.5} for t in (0.0, 0.5, 1.0)]
    cm.publish_message("box/heater", {"mode": "boost"})
    scheduler.run_until(11.25)  # applied on the loop thread, at once
    assert box.applied == [("heater", {"mode": "boost"}, 1.0)]


def test_a_failing_simulator_is_logged_once_then_counted_and_the_loop_goes_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    managed, _, scheduler, readings = started(Box(fail_from=0.5))
    with caplog.at_level(logging.ERROR, logger="rasm.platform"):
        scheduler.run_until(12.0)
    assert len(readings) == 1
    failures = [r for r in caplog.records if "sensor unplugged" in r.getMessage()]
    assert len(failures) == 1
    assert managed.logs.totals == {
        "the simulator's step failed: RuntimeError: sensor unplugged": 4
    }


def test_a_step_that_returns_no_readings_dict_is_reported(caplog) -> None:
    class Wrong(Box):
        def step(self, time, dt):
            return ["not", "a", "dict"]

    _, _, scheduler, readings = started(Wrong())
    with caplog.at_level(logging.ERROR, logger="rasm.platform"):
        scheduler.run_until(10.0)
    assert readings == []
    assert "must return {topic: payload} or None, not list" in caplog.text
