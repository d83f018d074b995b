"""The fallback switch: a Simplex-style safe fallback, run by its chart (fallback.yaml).

The app declares per effector a fallback action, proved legitimate in every context the rules
admit before the run starts (:func:`prove_fallback`). The switch watches its triggers — a veto
property the checker cannot vouch for, the managed system lost, ``after_failures`` failed
iterations with no adaptation reaching Execute (:class:`FailedIterations`) — and tells its
chart: ``trigger`` engages the fallback (its actions go out through the Adaptation Manager like
any other, signed, traced and checked), ``clear`` starts the dwell after which control is handed
back. While the chart is not ``nominal``, the Adaptation Manager holds back every other action
(:meth:`FallbackHold.holds`) but corrective ones.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rasm.errors import SourceError, SourceErrors
from rasm.platform.action_outcome import Emit, perform_and_trace
from rasm.platform.block import Block
from rasm.platform.components import Action, Plan
from rasm.platform.manifest import AppManifest, Fallback, manifest_location
from rasm.platform.protocols import Adapter, LoopStats, PlanRegistry, Vetoes
from rasm.times import format_seconds

if TYPE_CHECKING:
    from sismic.model import MacroStep

    from rasm.properties.monitor import Verdict
    from rasm.rules import Rules, RuleSet
    from rasm.rules.fixed_plan import FixedPlanProof

__all__ = [
    "FailedIterations",
    "FallbackHold",
    "FallbackSwitch",
    "check_fallback_legitimate",
    "prove_fallback",
]

_log = logging.getLogger("rasm.fallback")

PROVED = "the fallback actions, proved legitimate in every context before the run"


def prove_fallback(
    fallback: Fallback, rules: Sequence[Rules]
) -> list[tuple[Rules, FixedPlanProof]]:
    """The proof of the fallback actions against each rule set (together, as one plan: the
    Trustworthiness Manager judges each action with the fallback plan's values)."""
    from rasm.rules.fixed_plan import prove_fixed_plan

    return [(rule_set, prove_fixed_plan(rule_set, fallback.values)) for rule_set in rules]



def check_fallback_legitimate(m: AppManifest, rule_sets: Sequence[RuleSet]) -> None:
    """Refuse the app (at its fallback actions in app.yaml) unless z3 proved every fallback
    action legitimate in every context the rules admit."""
    assert m.fallback is not None
    problems = [
        SourceError(
            f"the fallback actions are not legitimate in every context the rules of "
            f"{rules.source} admit: {proof.explanation()}",
            manifest_location(m, ["fallback", "actions"]),
        )
        for rules, proof in prove_fallback(m.fallback, [r.rules for r in rule_sets])
        if not proof.legitimate
    ]
    if problems:
        raise SourceErrors(problems)

@dataclass
class FailedIterations:
    """The stage_failures trigger, from the loop's statistics read between ticks.

    An iteration failed when a stage failed or overran, the adaptation was cancelled after its
    replans, or an anomaly got no plan. The trigger holds from the ``threshold``-th failed
    iteration with no adaptation reaching Execute in between (an iteration without an anomaly
    neither counts nor resets, so a planner that fails on every anomaly is caught however rare
    anomalies are). It stops holding at an adaptation that reaches Execute (an action held
    back or refused by a check is not a failure of the loop's stages) or after ``threshold``
    iterations in a row without a failure."""

    threshold: int = 3
    consecutive: int = 0  # failed iterations since the last adaptation that reached Execute
    clean: int = 0  # iterations without a failure since the last failed one
    _seen: tuple[int, int, int, int] = (0, 0, 0, 0)

    @property
    def holds(self) -> bool:
        return self.consecutive >= self.threshold

    def update(self, stats: LoopStats) -> None:
        now = (
            stats.iterations,
            sum(stats.failed_stages.values()) + sum(stats.timeouts.values()) + stats.cancelled,
            stats.anomalies,
            stats.executed + stats.dropped,  # anomalies whose plan reached Execute
        )
        iterations, failed, anomalies, ended = (a - b for a, b in zip(now, self._seen, strict=True))
        if not iterations:
            return
        self._seen = now
        # an anomaly that neither failed nor reached Execute got no plan
        if failed or anomalies > ended + failed:
            self.consecutive += max(failed, anomalies - ended, 1)
            self.clean = 0
            return
        self.clean += iterations
        if ended or (self.holds and self.clean >= self.threshold):
            self.consecutive = 0


class FallbackHold:
    """What the fallback switch tells the Adaptation Manager: whether an action is held back.

    Made before both: the switch writes it (its chart's state after each step, the kinds of
    trigger that held, the veto verdicts it has not read yet), the Adaptation Manager reads it.
    ``vetoes`` says why a veto verdict stops actions (the Trustworthiness Manager).
    """

    def __init__(self, vetoes: Vetoes) -> None:
        self.vetoes = vetoes
        # the switch's chart: nominal, fallback or recovering, else the switch's mode
        self.state = "instantiated"
        self.reason = "no trigger"  # why the fallback was engaged last
        self.kinds: set[str] = set()  # the kinds of trigger that held at the last evaluation
        # the first verdict of each veto property that did not vouch since the triggers were
        # last read: a later verdict of the same batch that vouches again must not hide it
        self.unread: dict[str, Verdict] = {}

    def holds(self, action: Action) -> str | None:
        """Why ``action`` is held back (the fallback holds the effectors), or None."""
        if action.kind == "fallback":
            return None
        state = self.state
        if state == "nominal":
            if self.unread:  # the evaluation that engages the fallback has not run yet
                return f"the fallback is engaging: {'; '.join(self.unread_reasons())}"
            return None
        if state in ("fallback", "recovering"):
            return f"the fallback holds the effectors ({state}): {self.reason}"
        return f"the fallback switch is {state}"  # fail closed: no switch, no action

    def correctable(self) -> bool:
        """Whether a corrective action may pass: the fallback holds for vetoes alone."""
        return self.state == "fallback" and self.kinds == {"veto"}

    def unread_reasons(self, skip: Collection[str] = ()) -> list[str]:
        """Why each veto verdict not read yet stops actions (but those of ``skip``)."""
        reasons = (self.vetoes.veto_reason(name, verdict)
                   for name, verdict in self.unread.items() if name not in skip)
        return [why for why in reasons if why is not None]


class FallbackSwitch(Block):
    """Fallback switch (fb): :meth:`evaluate` the triggers, tell the chart, send the fallback
    through ``adapter`` (the Adaptation Manager); what it holds back is said in ``hold``."""

    chart_name = "fallback"
    short_name = "fb"

    def __init__(
        self,
        *,
        spec: Fallback,
        hold: FallbackHold,
        adapter: Adapter,
        plans: PlanRegistry,
        vetoes: Vetoes,
        online: Callable[[], bool],
        stats: LoopStats,
        emit: Emit,
        veto_properties: Collection[str],
        submit: Callable[[Callable[[], object]], object],
        plan_prefix: str = "",
        **kw: Any,
    ) -> None:
        self.spec = spec
        self.hold = hold
        self.adapter = adapter
        self.plans = plans
        self.vetoes = vetoes
        self.veto_properties = veto_properties
        self.submit = submit  # hands a job to the loop, to run after the job in hand
        self._veto_good: dict[str, bool] = {}  # each veto property's latest: vouches or not
        self._evaluation_due = False  # an evaluation is submitted and has not run yet
        self.online = online
        self.stats = stats
        self.emit = emit
        self.plan_prefix = plan_prefix
        self.failures = FailedIterations(spec.after_failures)
        self.engagements = 0
        self.pending: dict[str, dict[str, Any]] = {}  # fallback actions not delivered yet
        self._plan: Plan | None = None
        super().__init__(context={"dwell": spec.dwell}, **kw)

    def send(self, event: str | None, **data: Any) -> list[MacroStep]:
        steps = super().send(event, **data)
        # what the Adaptation Manager reads: the chart as this step left it
        self.hold.state, self.hold.reason = self.state, self.trigger_reason()
        return steps

    @property
    def state(self) -> str:
        """``nominal``, ``fallback`` or ``recovering`` (or the block's mode when not running)."""
        for state in ("nominal", "fallback", "recovering"):
            if state in self.configuration:
                return state
        return self.mode

    def trigger_reason(self) -> str:
        return str(self.interpreter.context.get("trigger_reason") or "no trigger")

    def triggers(self) -> list[str]:
        """The triggers that hold now, each with its reason."""
        held: list[str] = []
        kinds: set[str] = set()
        when = self.spec.when
        if "managed_system_lost" in when and not self.online():
            held.append("managed system lost")
            kinds.add("managed_system_lost")
        if "stage_failures" in when:
            self.failures.update(self.stats)
            if self.failures.holds:
                held.append(
                    f"{self.failures.consecutive} failed iterations since the last adaptation"
                )
                kinds.add("stage_failures")
        if "veto" in when:
            vetoing = self.vetoes.vetoing()
            # a veto that held only between two readings of the triggers counts too
            vetoes = [*vetoing.values(), *self.hold.unread_reasons(skip=vetoing)]
            self.hold.unread.clear()
            held.extend(vetoes)
            if vetoes:
                kinds.add("veto")
        self.hold.kinds = kinds
        return held

    def evaluate(self) -> None:
        """Read the triggers and tell the chart; retry fallback actions not delivered yet."""
        self._evaluation_due = False
        if self.mode != "initialized":
            return
        held = self.triggers()
        state = self.state
        if held and state in ("nominal", "recovering"):
            self.send("trigger", reason="; ".join(held))
        elif not held and state == "fallback":
            self.send("clear")
        if self.pending and self.state != "nominal":
            self._deliver()

    def watch_verdict(self, verdict: Verdict) -> None:
        """A veto property that starts or stops vouching has the triggers read at once (on the
        loop, after the job in hand) rather than at the next tick.

        Every verdict that does not vouch reaches the triggers, whatever follows it: it is kept
        until they are read (and holds the loop's actions back meanwhile), so a violation that
        a later verdict of the same batch clears still engages the fallback."""
        name = verdict.property
        if name not in self.veto_properties:
            return
        good = verdict.value is True and verdict.error is None
        changed = self._veto_good.get(name) != good
        self._veto_good[name] = good
        # (engaged already, the switch need not remember one: the fallback holds anyway)
        if not good and "veto" in self.spec.when and self.state != "fallback":
            self.hold.unread.setdefault(name, verdict)
        if (changed or self.hold.unread) and not self._evaluation_due:
            self._evaluation_due = True
            self.submit(self.evaluate)

    # ------------------------------------------------------------------ chart hooks

    def on_enter_fallback(self) -> None:
        if self._plan is None:  # engaged (not back from recovering): the actions go out
            reason = self.trigger_reason()
            _log.warning("fallback engaged: %s", reason)
            self.emit(
                self.clock.time,
                {"fallback": "engaged", "explanation": f"fallback engaged: {reason}"},
            )
            self.engagements += 1
            self._plan = Plan(
                self.spec.values,
                id=f"{self.plan_prefix}f{self.engagements}",
                explanation="the fallback actions",
            )
            self.pending = dict(self.spec.actions)
            self.plans.accept_plan(self._plan)
            self._deliver()

    def on_enter_nominal(self) -> None:
        if self._plan is not None:
            self.plans.forget_plan(self._plan.id)
        self._plan = None
        self.pending = {}

    def on_event_sent(self, name: str, data: dict[str, Any]) -> None:
        if name == "released":
            held_for = format_seconds(data.get("held_for"))
            _log.warning("fallback released after %s s without a trigger", held_for)
            self.emit(
                self.clock.time,
                {
                    "fallback": "released",
                    "explanation": f"control handed back: no trigger for {held_for} s",
                },
            )

    def _deliver(self) -> None:
        plan = self._plan
        if plan is None or not self.pending:
            return
        # z3 proved the plan legitimate in every context before the run: its record says so
        # before each delivery, as Legitimate's acceptance comes before a loop plan's actions
        self.emit(self.clock.time, {"legitimate": True, "plan": plan.id, "explanation": PROVED})
        for effector, payload in list(self.pending.items()):
            action = Action(effector, dict(payload), plan.id, "fallback")
            if perform_and_trace(self.adapter.perform_adaptation, action, self.emit,
                                 self._now).sent:
                del self.pending[effector]

    def _now(self) -> float:
        return self.clock.time
