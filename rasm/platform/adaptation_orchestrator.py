"""The Adaptation Orchestrator: the MAPLE-K loop, run by its chart (adaptation_orchestrator.yaml).

Each ``tick`` the chart walks monitoring → analysing → planning → legitimating → executing. On
entering a stage state this block runs the user's stage code (with a time budget, see
:mod:`rasm.platform.stages`), writes what happened to the adaptation trace, and answers with the
stage's outcome event. The chart decides what comes next: a rejected plan goes back to planning a
bounded number of times, an overrun or failed stage ends the iteration, and no action is executed
from an iteration that did not pass Legitimate.
"""

from __future__ import annotations

import logging
import traceback
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from sismic.clock import SimulatedClock

from rasm.errors import is_interrupt
from rasm.knowledge.base import KnowledgeBase
from rasm.platform.action_outcome import Emit, perform_and_trace
from rasm.platform.block import Block, shared_chart
from rasm.platform.chart_stages import NoAnswer
from rasm.platform.components import (
    Plan,
    StageContext,
    StageError,
    as_actions,
    as_anomaly,
    as_plan,
    as_signals,
    as_verdict,
    describe_failure,
)
from rasm.platform.protocols import Adapter, LoopStats, PlanRegistry, Register, StageTimer
from rasm.platform.stages import StageOutcome, StageRunner
from rasm.resources import platform_monitors
from rasm.times import format_seconds

if TYPE_CHECKING:
    from rasm.rules import RuleSet
    from rasm.twin import DigitalTwin

__all__ = ["AdaptationOrchestrator", "Repairer"]

_log = logging.getLogger("rasm.loop")


# (rejected plan, knowledge snapshot) -> the nearest plan the rules accept, or None
Repairer = Callable[[Plan, dict[str, Any]], Plan | None]


class AdaptationOrchestrator(Block):
    """Adaptation Orchestrator (ao): ``orchestration_loop`` is its chart; this is its driver."""

    chart_name = "adaptation_orchestrator"
    short_name = "ao"

    def __init__(
        self,
        *,
        components: dict[str, object],
        knowledge: KnowledgeBase,
        rules: list[RuleSet],
        register: Register,
        emit: Emit,
        adapter: Adapter,
        plans: PlanRegistry,
        timer: StageTimer,
        stage_budget: float = 1.0,
        max_replans: int = 2,
        max_actions: int = 16,
        isolate_stages: bool = True,
        twin: DigitalTwin | None = None,
        twin_properties: Sequence[tuple[str, str]] = (),
        twin_horizon: float = 20.0,
        twin_dt: float = 0.5,
        plan_prefix: str = "",
        repair: Repairer | None = None,
        **kw: Any,
    ) -> None:
        # legitimate.repair: after a rejection, the next plan is the nearest legitimate one
        self.repair = repair
        self._repaired_from: str | None = None  # the rejected plan the plan in hand repairs
        self._repairs: set[str] = set()  # plans of this iteration that are repairs
        self.twin = twin
        self.twin_properties = list(twin_properties)
        if twin is not None:
            from rasm.twin import PredictionChecker

            self._twin_checker = PredictionChecker(self.twin_properties)  # parsed once
        self.twin_horizon = twin_horizon
        self.twin_dt = twin_dt
        self.components = components
        self.knowledge = knowledge
        self.rules = rules
        self.register = register
        self.emit = emit
        self.adapter = adapter
        self.plans = plans
        self.timer = timer
        self.stage_budget = stage_budget
        self.max_actions = max_actions
        self.runner = StageRunner(isolate=isolate_stages)
        self.stats = LoopStats()
        self.ctx: StageContext | None = None
        self._plans = 0
        self.plan_prefix = plan_prefix  # plan ids are f"{plan_prefix}p{n}"
        super().__init__(context={"stage_budget": stage_budget, "max_replans": max_replans}, **kw)
        # the property statecharts of monitors/ watch every step of the loop (docs/statecharts.md)
        for path in platform_monitors():
            self.interpreter.bind_property_statechart(shared_chart(path))

    # ------------------------------------------------------------------ driving

    def orchestration_loop(self) -> None:
        """One loop iteration (the RoboSAPIENS ``orchestrationLoop``): a ``tick`` for the chart."""
        self.send("tick")

    def on_enter_idle(self) -> None:
        self.ctx = None
        self._repairs.clear()

    def on_termination(self) -> None:
        self.runner.close()

    # ------------------------------------------------------------------ stages

    def _stage(
        self,
        stage: str,
        body: Callable[[StageContext, Any], str],
        func: Callable[[StageContext], Any] | None = None,
    ) -> None:
        """Run the user's code for ``stage`` (or ``func``), then ``body`` with its result; post
        the outcome event ``body`` returns, or ``stage_failed``."""
        ctx = self.ctx
        start = self.clock.time
        func = func or getattr(self.components.get(stage), stage, None)
        if func is None:
            outcome = StageOutcome(True, None)
        else:
            outcome = self.runner.call(func, self.stage_budget, ctx)
        self.timer.record_stage(stage, start, outcome.duration)
        self.emit(start, {"stage": stage, "duration": round(outcome.duration, 9)})
        # a stage chart that sends no outcome has not answered: it fails as an overrun does
        no_answer = isinstance(outcome.error, NoAnswer)
        if outcome.timed_out or no_answer:
            self.stats.timeouts[stage] += 1
            if no_answer:
                self.logs.log(
                    _log, logging.WARNING, f"{outcome.error}: iteration cancelled"
                )
                why = f"{stage} stage failed to answer: {outcome.error}"
            else:
                self.logs.log(
                    _log,
                    logging.WARNING,
                    f"{stage} stage overran its {format_seconds(self.stage_budget)} s budget",
                    "%s stage overran its %s s budget (%s s): iteration cancelled",
                    stage,
                    format_seconds(self.stage_budget),
                    format_seconds(outcome.duration),
                )
                why = f"{stage} stage overran its time budget"
            self.emit(start, {"explanation": why})
            if isinstance(self.clock, SimulatedClock):
                # an overrun costs the whole budget, so the chart's after() timer fires
                self.clock.time = start + self.stage_budget
            return  # the chart's after(stage_budget) transition ends the iteration
        if not outcome.ok:
            self._fail(stage, describe_failure(outcome.error), outcome.traceback)
            return
        try:
            event = body(ctx, outcome.result)
        except StageError as exc:
            self._fail(stage, str(exc), "")
            return
        except Exception as exc:  # an odd result the checks above missed: fail the stage
            self._fail(stage, describe_failure(exc), traceback.format_exc())
            return
        self.post(event)

    def _fail(self, stage: str, reason: str, tb: str) -> None:
        self.stats.failed_stages[stage] += 1
        # the same failure again (same stage, type and message): counted, not logged in full
        self.logs.log(
            _log,
            logging.ERROR,
            f"{stage} stage failed: {reason}",
            "%s stage failed: %s%s",
            stage,
            reason,
            f"\n{tb.rstrip()}" if tb else "",
        )
        self.emit(self.clock.time, {"explanation": f"{stage} stage failed: {reason}"})
        self.post("stage_failed", stage=stage, reason=reason)

    def on_enter_monitoring(self) -> None:
        self.stats.iterations += 1
        self.ctx = StageContext(self.knowledge, self.clock.time, self.stats.iterations)
        self._stage("monitor", self._monitored)

    def _monitored(self, ctx: StageContext, result: Any) -> str:
        signals = as_signals(result)
        if signals:
            self.register(signals, self.clock.time)
        return "monitored"

    def on_enter_analysing(self) -> None:
        self._stage("analyse", self._analysed)

    def _analysed(self, ctx: StageContext, result: Any) -> str:
        anomaly = as_anomaly(result)
        if anomaly is None:
            return "no_anomaly"
        ctx.anomaly = anomaly
        ctx.rejections = []
        self.stats.anomalies += 1
        self.emit(self.clock.time, {"anomaly": True, "explanation": anomaly.reason})
        return "anomaly"

    def on_enter_planning(self) -> None:
        self._repaired_from = None
        ctx = self.ctx
        if self.repair is not None and ctx is not None and ctx.rejections:
            rejected = ctx.rejections[-1][0]
            if rejected.id not in self._repairs:  # a rejected repair goes back to the planner
                self._stage("plan", self._planned, lambda c: self._repair_or_plan(c, rejected))
                return
        self._stage("plan", self._planned)

    def _repair_or_plan(self, ctx: StageContext, rejected: Plan) -> Any:
        """The nearest legitimate plan to ``rejected``; the user's planner if there is none."""
        repaired = self.repair(rejected, self.knowledge.snapshot())
        if repaired is not None:
            self._repaired_from = rejected.id
            return repaired
        planner = getattr(self.components.get("plan"), "plan", None)
        return planner(ctx) if planner is not None else None

    def _planned(self, ctx: StageContext, result: Any) -> str:
        self._plans += 1
        plan = as_plan(result, f"{self.plan_prefix}p{self._plans}")
        if plan is None:
            self.emit(self.clock.time, {"explanation": "no plan for the anomaly"})
            return "no_plan"
        ctx.plan = plan
        self.stats.plans += 1
        record = {"planned": True, "plan": plan.id}
        record.update(
            {
                k: v
                for k, v in plan.values.items()
                if isinstance(v, int | float | str | bool) and k not in record
            }
        )
        if self._repaired_from is not None:
            record["repaired_from"] = self._repaired_from
            self._repairs.add(plan.id)
        if plan.explanation:
            record["explanation"] = plan.explanation
        self.emit(self.clock.time, record)
        return "planned"

    def on_enter_legitimating(self) -> None:
        self._stage("legitimate", self._legitimated)

    def _legitimated(self, ctx: StageContext, result: Any) -> str:
        plan = ctx.plan
        assert plan is not None
        ok, why = as_verdict(result)
        broken: list[str] = []
        reasons: list[str] = []
        context = self.knowledge.snapshot()
        for rules in self.rules:
            decision = rules.evaluate(plan.values, context)
            if not decision.accepted:
                broken.extend(decision.broken)
                reasons.append(decision.explanation())
        if not ok:
            broken.append("application")
            reasons.append(why)
        if not broken and self.twin is not None:
            for name, why in self._twin_check(plan, context):
                broken.append(f"twin:{name}")
                reasons.append(why)
        if broken:
            self.stats.rejected += 1
            ctx.rejections.append((plan, broken, "; ".join(reasons)))
            self.emit(
                self.clock.time,
                {
                    "rejected": True,
                    "plan": plan.id,
                    "broken_rules": broken,
                    "explanation": "; ".join(reasons),
                },
            )
            return "rejected"
        self.stats.accepted += 1
        self.plans.accept_plan(plan)
        self.emit(self.clock.time, {"legitimate": True, "plan": plan.id})
        return "accepted"

    def _twin_check(self, plan: Plan, context: dict[str, Any]) -> list[tuple[str, str]]:
        """Simulate ``plan`` on the digital twin: the properties it would break where keeping
        the current settings would not (an absolute check would reject the plan that helps
        most whenever every option leaves the band; docs/twin.md)."""
        from rasm.twin import worse_than_baseline

        try:
            worse = worse_than_baseline(
                self.twin, self._twin_checker, plan.values, context, self.twin_horizon, self.twin_dt
            )
        except BaseException as exc:  # fail closed: a plan the twin cannot judge is not legitimate
            if is_interrupt(exc):
                raise
            return [("simulation", f"the twin could not simulate the plan: {exc}")]
        return list(worse.items())

    def on_enter_executing(self) -> None:
        self._stage("execute", self._executed)

    def _executed(self, ctx: StageContext, result: Any) -> str:
        plan = ctx.plan
        assert plan is not None
        actions = as_actions(result, plan.id)
        if len(actions) > self.max_actions:
            # a flood would hold the loop (each action is checked and sent in turn) and the
            # effector: the whole lot is refused, so no partial adaptation goes out either
            raise StageError(
                f"execute returned {len(actions)} actions, more than loop.max_actions "
                f"({self.max_actions}): none was sent"
            )
        executed = 0
        for action in actions:
            outcome = perform_and_trace(self.adapter.perform_adaptation, action, self.emit,
                                        self._now)
            if outcome.sent:
                executed += 1
        self.plans.forget_plan(plan.id)
        if executed:
            self.stats.executed += 1
            return "executed"
        self.stats.dropped += 1
        if not actions:
            self.emit(
                self.clock.time,
                {"dropped": True, "plan": plan.id, "explanation": "execute produced no action"},
            )
        return "dropped"

    def _now(self) -> float:
        return self.clock.time

    def on_event_sent(self, name: str, data: dict[str, Any]) -> None:
        if name == "adaptation_cancelled":
            self.stats.cancelled += 1
            self.emit(
                self.clock.time,
                {
                    "explanation": f"adaptation cancelled after "
                    f"{data.get('replans', '?')} rejected replans"
                },
            )
