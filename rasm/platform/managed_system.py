"""The managed system simulated in the platform's process: the app's simulator.

The simulator is stepped on the loop's clock and publishes its readings on the probe topics;
the actions that reach an effector topic are applied to it. It meets the managing side only
on the transport, exactly as a real robot would.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from rasm.comm import Message, Subscription
from rasm.comm.transport import Callback
from rasm.errors import RasmError, is_interrupt
from rasm.logs import RepeatedLogs
from rasm.platform.components import describe_failure
from rasm.platform.manifest import Effector
from rasm.platform.scheduler import Scheduler

__all__ = ["Bus", "ManagedSystem", "Simulator"]

_log = logging.getLogger("rasm.platform")

Apply = Callable[[dict[str, Any]], Any]
"""Applies one action payload."""


class Simulator(Protocol):
    """The app's simulated managed system (manifest ``managed_system.simulator``)."""

    def step(self, time: float, dt: float) -> dict[str, dict[str, Any]] | None:
        """Advance ``dt`` seconds to ``time``; return the readings, ``{topic: payload}``."""

    def apply(self, effector: str, action: dict[str, Any], time: float) -> Any:
        """Act on an action received by effector ``effector``."""


class Bus(Protocol):
    """Where the readings go and the actions come from: the Communication Manager."""

    def publish_message(self, topic: str, payload: dict[str, Any]) -> None: ...

    def subscribe(self, pattern: str, callback: Callback) -> Subscription: ...


def describe_activity(managed: ManagedSystem) -> list[str]:
    """What the managed side did, one line each, for the run's summary."""
    def counts(counter: Counter[str]) -> str:
        return ", ".join(f"{name} {n}" for name, n in sorted(counter.items()))

    def many(n: int, what: str) -> str:
        return f"{n} {what}" if n == 1 else f"{n} {what}s"

    published, applied = sum(managed.published.values()), sum(managed.applied.values())
    lines = [f"{many(managed.steps, 'simulator step')}, {many(published, 'reading')} published"
             + (f" ({counts(managed.published)})" if published else "")]
    lines.append(f"{many(applied, 'action')} applied"
                 + (f" ({counts(managed.applied)})" if applied
                    else ": none reached the simulator"))
    if managed.failures:
        lines.append(f"{many(managed.failures, 'simulator step or apply')} failed (logged)")
    if managed.unsent:
        lines.append(f"{many(managed.unsent, 'reading')} the transport refused (logged)")
    return lines


class ManagedSystem:
    """Steps ``simulator`` every ``period`` seconds and applies the actions its effectors get.

    The simulator is user code: whatever it raises is logged (once in full, then counted in
    ``logs``) and the run goes on.
    """

    def __init__(
        self,
        simulator: Simulator,
        *,
        period: float,
        effectors: Mapping[str, Effector],
        logs: RepeatedLogs,
    ) -> None:
        self.simulator = simulator
        self.period = period
        self.effectors = effectors
        self.logs = logs
        self._gates: dict[str, Apply] = {}
        self._started_at = 0.0
        # what the managed side did, for the run's summary
        self.steps = 0  # simulator steps taken (whether or not they raised)
        self.published: Counter[str] = Counter()  # readings put on the bus, by topic
        self.applied: Counter[str] = Counter()  # actions the simulator took, by effector
        self.failures = 0  # simulator steps and applies that raised
        self.unsent = 0  # readings the transport refused

    def start(
        self,
        bus: Bus,
        scheduler: Scheduler,
        *,
        started_at: float,
        gate: Callable[[Apply, str], Apply],
    ) -> None:
        """Subscribe to the effector topics and step the simulator from now on.

        ``started_at`` is the platform clock's time the simulated world starts at (its own
        time is 0 then); ``gate(apply, topic)`` wraps what applies an action received on
        ``topic`` (checking signatures when actions are signed).
        """
        self._bus = bus
        self._scheduler = scheduler
        self._started_at = started_at
        self._gate = gate
        for name, effector in self.effectors.items():
            if effector.call is not None:
                continue  # a service or action is served by the robot, not by a simulator
            bus.subscribe(
                effector.topic, lambda message, name=name: self._on_effector(name, message)
            )
        scheduler.every(self.period, self.step)

    def _on_effector(self, name: str, message: Message) -> None:
        # on the transport's thread: the action is applied on the loop's
        payload = dict(message.payload)
        gate = self._gates.get(name)
        if gate is None:
            gate = self._gates[name] = self._gate(
                lambda action, name=name: self.apply(name, action), message.topic
            )
        self._scheduler.submit(lambda: gate(payload))

    def apply(self, effector: str, action: dict[str, Any]) -> None:
        try:
            self.simulator.apply(effector, action, self._scheduler.now() - self._started_at)
        except BaseException as exc:  # the simulator is user code: never fatal
            if is_interrupt(exc):
                raise
            self.failures += 1
            what = f"the simulator's apply({effector!r}) failed: {describe_failure(exc)}"
            self.logs.log(_log, logging.ERROR, what, exc_info=exc)
        else:
            self.applied[effector] += 1

    def step(self) -> None:
        """Step the simulator once and publish its readings."""
        # the simulated world starts at 0 whatever the managing system's restored timeline
        self.steps += 1
        try:
            readings = self.simulator.step(self._scheduler.now() - self._started_at, self.period)
        except BaseException as exc:  # the simulator is user code: never fatal
            if is_interrupt(exc):
                raise
            self.failures += 1
            what = f"the simulator's step failed: {describe_failure(exc)}"
            self.logs.log(_log, logging.ERROR, what, exc_info=exc)
            return
        if readings is not None and not isinstance(readings, dict):
            what = (
                "the simulator's step must return {topic: payload} or None, "
                f"not {type(readings).__name__}"
            )
            self.failures += 1
            self.logs.log(_log, logging.ERROR, what)
            return
        for topic, payload in (readings or {}).items():
            try:
                self._bus.publish_message(topic, payload)
            except RasmError as exc:  # a topic or payload the transport refuses
                self.unsent += 1
                what = f"the simulator's reading on {topic!r} was not published: {exc}"
                self.logs.log(_log, logging.ERROR, what)
            else:
                self.published[topic] += 1
