"""Service and action effectors: each action the Trustworthiness Checker lets through calls its
effector's ROS 2 service, or sends a goal to its action, off the loop thread.

The loop is single-threaded and a call may take seconds (an action minutes), so a call runs on
a thread of its own and its outcome comes back to the loop as a job, as the transports deliver
messages: the response's (an action's result's) fields go into knowledge, and so does each
feedback as it arrives. A call that fails — no server, a timeout, a refused, aborted or
cancelled goal, an error reply — fails visibly: logged, an ``effector_failed`` trace record
saying why, a count in the run's summary. Nothing about a failed call reaches knowledge.

A goal still running when the fallback engages or a veto property stops vouching is
cancelled (the fallback's own goals go on); so is every goal still running when the run ends.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from rasm.logs import RepeatedLogs
from rasm.platform.action_outcome import Emit
from rasm.platform.components import Action
from rasm.platform.manifest import Effector
from rasm.platform.protocols import Register

if TYPE_CHECKING:
    from rasm.properties.monitor import Verdict

__all__ = ["CallCounts", "CallEffectors", "Caller", "effector_calls"]

_log = logging.getLogger("rasm.calls")

#: how long the end of a run waits for the calls still running (their cancels go out first)
END_WAIT = 2.0


class Goal(Protocol):
    """A goal being pursued (:class:`rasm.ros2.calls.ActionGoal`)."""

    goal_id: bytes

    def cancel(self, reason: str) -> None: ...


class Caller(Protocol):
    """What calls services and pursues actions on a ROS 2 network (:mod:`rasm.ros2.calls`).
    Both block until the answer and raise on every failure, saying why."""

    def call(self, service: str, typename: str, request: Mapping[str, Any],
             timeout: float) -> dict[str, Any]: ...

    def pursue(self, action: str, typename: str, goal_fields: Mapping[str, Any],
               timeout: float, feedback: Callable[[dict[str, Any]], object],
               goal: Any) -> dict[str, Any]: ...


@dataclass
class CallCounts:
    """One effector's calls so far: how they ended, and the last failure's reason."""

    succeeded: int = 0
    failed: int = 0
    cancelled: int = 0
    unfinished: int = 0  # still running when the run ended
    last_failure: str = ""

    def describe(self) -> str:
        parts = [f"{n} {what}" for what, n in (
            ("succeeded", self.succeeded), ("failed", self.failed),
            ("cancelled", self.cancelled), ("unfinished at the end", self.unfinished),
        ) if n]
        return ", ".join(parts) or "none"


@dataclass(eq=False)
class _Running:
    effector: Effector
    action: Action
    goal: Goal | None  # an action's goal (None: a service call)
    thread: threading.Thread | None = None
    cancelled_because: str | None = None
    done: bool = False
    # what the worker thread found: (answer, None) or (None, why it failed)
    outcome: tuple[dict[str, Any] | None, str | None] | None = None
    feedback: list[dict[str, Any]] = field(default_factory=list)


class CallEffectors:
    """Runs the calls of service and action effectors (:meth:`start`, from the action path).

    ``caller`` makes the calls (on worker threads); ``submit`` hands a job to the loop
    thread; ``register(values, time)`` puts values in knowledge (and the trace);
    ``emit(time, record)`` writes a trace record; ``now`` is the loop's time.
    ``veto_reason(name, verdict)`` says why a verdict of veto property ``name`` stops actions
    (None: it vouches): a running goal is then cancelled.
    """

    def __init__(
        self,
        caller: Caller,
        *,
        submit: Callable[[Callable[[], object]], object],
        register: Register,
        emit: Emit,
        now: Callable[[], float],
        veto_properties: Collection[str] = (),
        veto_reason: Callable[[str, Verdict], str | None] | None = None,
        logs: RepeatedLogs | None = None,
    ) -> None:
        self.caller = caller
        self.submit = submit
        self.register = register
        self.emit = emit
        self.now = now
        self.veto_properties = veto_properties
        self.veto_reason = veto_reason
        self.logs = logs if logs is not None else RepeatedLogs()
        self.counts: dict[str, CallCounts] = {}
        self.running: list[_Running] = []

    # -- the action path ----------------------------------------------------------------------
    def start(self, effector: Effector, action: Action, request: dict[str, Any]) -> str:
        """Start ``effector``'s call with ``request`` (its request or goal message); what the
        ``executed`` record says. Loop thread."""
        from rasm.ros2.calls import ActionGoal

        goal = ActionGoal(os.urandom(16)) if effector.call == "action" else None
        running = _Running(effector, action, goal)
        self.counts.setdefault(effector.name, CallCounts())
        running.thread = threading.Thread(
            target=self._work, args=(running, request), daemon=True,
            name=f"rasm-{effector.call}-{effector.name}",
        )
        self.running.append(running)
        running.thread.start()
        if goal is not None:
            return (f"goal {goal.goal_id.hex()} sent to action {effector.topic} by effector "
                    f"{effector.name}; its result is traced when it comes")
        return (f"service {effector.topic} called by effector {effector.name}; its response "
                "is traced when it comes")

    def _work(self, running: _Running, request: dict[str, Any]) -> None:
        """The call, on its own thread; the outcome goes back to the loop as a job."""
        effector = running.effector
        assert effector.type is not None
        answer: dict[str, Any] | None = None
        why: str | None = None
        try:
            if running.goal is None:
                answer = self.caller.call(effector.topic, effector.type, request,
                                          effector.timeout)
            else:
                answer = self.caller.pursue(
                    effector.topic, effector.type, request, effector.timeout,
                    lambda feedback: self.submit(lambda: self._feedback(running, feedback)),
                    running.goal,
                )
        except Exception as exc:  # every failure fails the action, whatever raised it
            why = str(exc) or type(exc).__name__
        running.outcome = (answer, why)
        self.submit(lambda: self._finish(running))

    # -- outcomes (loop thread) ---------------------------------------------------------------
    def _feedback(self, running: _Running, feedback: dict[str, Any]) -> None:
        if running.done:
            return
        values = _read(running.effector.feedback, feedback)
        if values:
            self.register(values, self.now())

    def _finish(self, running: _Running) -> None:
        if running.done or running.outcome is None:
            return
        running.done = True
        self.running.remove(running)
        effector, plan = running.effector, running.action.plan
        counts = self.counts[effector.name]
        answer, why = running.outcome
        what = f"{effector.call} {effector.topic}"
        if why is None and answer is not None:
            counts.succeeded += 1
            values = _read(effector.response, answer)
            if values:
                self.register(values, self.now())
            self.emit(self.now(), {
                "effector_done": effector.name, "plan": plan,
                "explanation": f"effector {effector.name}: {what} succeeded",
            })
            return
        if running.cancelled_because is not None:
            counts.cancelled += 1
        else:
            counts.failed += 1
        reason = why or "no answer"
        counts.last_failure = reason
        self.logs.log(_log, logging.WARNING, f"effector {effector.name}: {what} failed",
                      "effector %s: %s failed: %s", effector.name, what, reason)
        self.emit(self.now(), {
            "effector_failed": effector.name, "plan": plan,
            "explanation": f"effector {effector.name}: {reason}",
        })

    # -- cancellation -------------------------------------------------------------------------
    def cancel_goals(self, reason: str) -> int:
        """Cancel every goal still running but the fallback's; how many were."""
        cancelled = 0
        for running in self.running:
            if running.goal is None or running.action.kind == "fallback":
                continue
            if running.cancelled_because is None:
                running.cancelled_because = reason
                running.goal.cancel(reason)
                cancelled += 1
        return cancelled

    def observe_record(self, time: float, record: dict[str, Any]) -> None:
        """A trace record (loop thread): the fallback engaging cancels the running goals."""
        if record.get("fallback") == "engaged" and self.running:
            self.cancel_goals("the fallback engaged")

    def observe_verdict(self, verdict: Verdict) -> None:
        """A verdict (loop thread): a veto property that stops vouching cancels the running
        goals."""
        if not self.running or verdict.property not in self.veto_properties:
            return
        why = self.veto_reason(verdict.property, verdict) if self.veto_reason else None
        if why is not None:
            self.cancel_goals(why)

    def close(self, wait: float = END_WAIT) -> None:
        """The end of the run: cancel every goal still running (the fallback's too), wait a
        little for the calls to end, and account for each (those still running count as
        unfinished)."""
        for running in self.running:
            if running.goal is not None and running.cancelled_because is None:
                running.cancelled_because = "the run ended"
                running.goal.cancel("the run ended")
        deadline = time.monotonic() + wait  # one wait for them all
        for running in list(self.running):
            if running.thread is not None:
                running.thread.join(max(deadline - time.monotonic(), 0.0))
            if running.outcome is not None:
                self._finish(running)
        for running in list(self.running):
            running.done = True
            self.running.remove(running)
            counts = self.counts[running.effector.name]
            counts.unfinished += 1
            counts.last_failure = "the run ended before the answer came"
            self.emit(self.now(), {
                "effector_failed": running.effector.name, "plan": running.action.plan,
                "explanation": f"effector {running.effector.name}: the run ended before "
                               f"{running.effector.call} {running.effector.topic} answered",
            })


def _read(signals: Mapping[str, Any], message: Mapping[str, Any]) -> dict[str, Any]:
    """The knowledge values an answer gives: each signal's field (a field the answer lacks
    is left out)."""
    from rasm.ros2 import FieldPath, RosError

    values = {}
    for key, signal in signals.items():
        try:
            values[key] = signal.scaled(FieldPath.parse(signal.field or key).read(message))
        except RosError:
            continue
    return values


def effector_calls(
    effectors: Mapping[str, Effector], transport: Any, **kw: Any
) -> CallEffectors | None:
    """The calls of ``effectors``' services and actions over a ROS 2 ``transport`` (None when
    none calls one); ``kw`` as :class:`CallEffectors` takes them."""
    if not any(e.call for e in effectors.values()):
        return None
    from rasm.ros2.calls import calls_for

    return CallEffectors(calls_for(transport), **kw)
