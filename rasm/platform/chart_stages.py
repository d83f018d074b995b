"""A MAPLE-K stage written as a statechart (``analyse: charts/analyse.yaml`` in app.yaml).

Each iteration the stage's chart receives one event named after the stage (``analyse``) and
answers it by sending the stage's outcome events (:data:`STAGE_OUTCOMES`) with ``send``. Before
that event its context holds, read-only:

``knowledge``   the knowledge, latest value per key (``knowledge.get('temperature')``)
``time``        the platform time of the iteration (s, to the nanosecond)
``iteration``   the iteration's number
``anomaly``     what Analyse found: ``{'reason': ..., **data}``, or None
``plan``        the plan's values (a dict), or None
``rejections``  how many plans were rejected for this anomaly so far

The chart keeps its own state and variables from one iteration to the next (that is what makes
hysteresis easy to write) and measures time by the platform's clock: ``after(2.0)`` on a
transition taken by the stage's event holds once the state has been active 2 s of platform time.

A chart that sends no outcome in the steps that follow the stage's event has not answered: the
stage fails as a Python stage that overran its budget does, and so does a chart that is still
busy when its budget runs out. A chart that never settles (its own events keep it stepping)
fails the stage after :data:`MAX_STEPS` steps.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sismic.model import Statechart

from rasm.errors import ExecutionError
from rasm.platform.components import Action, Anomaly, Plan, StageContext, StageError
from rasm.platform.modes import KnowledgeView
from rasm.statechart import Interpreter, SimulatedClock, load_statechart
from rasm.times import to_the_nanosecond

__all__ = ["MAX_STEPS", "STAGE_OUTCOMES", "ChartStage", "NoAnswer"]

STAGE_OUTCOMES: dict[str, tuple[str, ...]] = {
    "monitor": ("monitored",),
    "analyse": ("anomaly", "no_anomaly"),
    "plan": ("planned", "no_plan"),
    "legitimate": ("accepted", "rejected"),
    "execute": ("action", "no_action"),
}
"""The events a stage chart answers with. ``monitored`` carries the derived signals as its data;
``anomaly`` a ``reason`` and any data the planner needs; ``planned`` the plan's values (and an
optional ``explanation``); ``rejected`` a ``reason``; each ``action`` one ``effector`` and its
``payload`` (Execute may send several)."""


MAX_STEPS = 1000  # macro steps for one request: more means the chart never settles


class NoAnswer(StageError):
    """A stage chart sent no outcome for its stage's event."""


class ChartStage:
    """The component of one stage, driven by its chart: ``stage(ctx)`` (``analyse(ctx)``, …)
    sends the chart the stage's event and turns the outcomes it sends into the result a Python
    stage would return."""

    def __init__(self, chart: str | Path | Statechart, stage: str) -> None:
        if stage not in STAGE_OUTCOMES:
            raise ValueError(f"no stage {stage!r} (one of {', '.join(STAGE_OUTCOMES)})")
        self.stage = stage
        self.chart = chart if isinstance(chart, Statechart) else load_statechart(chart)
        self.clock = SimulatedClock()
        self.interpreter = Interpreter(self.chart, clock=self.clock)
        self._busy = False
        self._started = False
        # the method the orchestrator calls, named after the stage
        setattr(self, stage, self.answer)

    def __repr__(self) -> str:
        return f"<ChartStage {self.stage} {self.chart.name!r}>"

    def answer(self, ctx: StageContext) -> Any:
        """Run the chart on the stage's event; the stage's result from the outcomes it sent."""
        if self._busy:
            # an earlier request overran its budget and is still running on another thread
            raise StageError(f"the {self.stage} chart is still busy with an earlier iteration")
        self._busy = True
        try:
            sent = self._request(ctx)
        finally:
            self._busy = False
        return self._result(sent)

    def _request(self, ctx: StageContext) -> list[tuple[str, dict[str, Any]]]:
        self.clock.time = max(self.clock.time, ctx.time)
        context = self.interpreter.context
        anomaly = ctx.anomaly
        context.update(
            knowledge=KnowledgeView(ctx.knowledge),
            time=to_the_nanosecond(ctx.time),  # as the chart's clock reads it: 0.3, not 0.1 * 3
            iteration=ctx.iteration,
            anomaly=None if anomaly is None else {**anomaly.data, "reason": anomaly.reason},
            plan=None if ctx.plan is None else dict(ctx.plan.values),
            rejections=len(ctx.rejections),
        )
        if not self._started:
            self._started = True
            self._run()  # the initial step: enter the initial states (runs the preamble)
        self.interpreter.queue(self.stage)
        return self._run()

    def _run(self) -> list[tuple[str, dict[str, Any]]]:
        sent: list[tuple[str, dict[str, Any]]] = []
        for _ in range(MAX_STEPS):
            try:
                step = self.interpreter.execute_once()
            except ExecutionError as exc:
                # the step is rolled back: the chart stays where it was, and the stage fails
                raise StageError(f"the {self.stage} chart failed: {exc}") from exc
            if step is None:
                return sent
            sent += [(e.name, dict(e.data)) for e in step.sent_events]
        raise StageError(
            f"the {self.stage} chart did not settle within {MAX_STEPS} steps (does it answer "
            "an event it sends itself?)"
        )

    def _result(self, sent: list[tuple[str, dict[str, Any]]]) -> Any:
        outcomes = [(name, data) for name, data in sent if name in STAGE_OUTCOMES[self.stage]]
        if not outcomes:
            raise NoAnswer(
                f"the {self.stage} chart {self.chart.name!r} sent no outcome "
                f"({', '.join(STAGE_OUTCOMES[self.stage])}) for the '{self.stage}' event"
            )
        names = {name for name, _ in outcomes}
        if self.stage == "execute":
            if names == {"no_action"}:
                return []
            return [_action(data) for name, data in outcomes if name == "action"]
        if len(outcomes) > 1 and not (self.stage == "monitor" and names == {"monitored"}):
            raise StageError(
                f"the {self.stage} chart answered twice ({', '.join(n for n, _ in outcomes)}): "
                "one outcome per iteration"
            )
        name, data = outcomes[0]
        if self.stage == "monitor":
            signals: dict[str, Any] = {}
            for _, more in outcomes:
                signals.update(more)
            return signals or None
        if name == "anomaly":
            reason = data.pop("reason", "anomaly")
            return Anomaly(str(reason), data)
        if name == "planned":
            explanation = str(data.pop("explanation", ""))
            return Plan(data, explanation=explanation)
        if name == "rejected":
            return False, str(data.get("reason", "rejected by the application's legitimate chart"))
        return {"no_anomaly": None, "no_plan": None, "accepted": True}[name]


def _action(data: dict[str, Any]) -> Action:
    effector, payload = data.get("effector"), data.get("payload", {})
    if not isinstance(effector, str):
        raise StageError("execute chart: send('action', effector='name', payload={...})")
    if not isinstance(payload, dict):
        raise StageError(f"execute chart: the payload for {effector!r} must be a dict")
    return Action(effector, dict(payload))
