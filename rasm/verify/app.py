"""``rasm verify APP``: the charts ``rasm run`` would run, bound together as it binds them.

The system explored (a :class:`~rasm.verify.explore.System`) holds:

- the **orchestrator** (the app's replacement or the platform's chart) with the property
  statecharts of ``monitors/`` bound to it, driven as its driver drives it: entering a stage
  state runs that stage and answers with the stage's outcome;
- the **stage charts** (``analyse: charts/analyse.yaml``): asked with their stage's event, with
  ``knowledge``, ``anomaly``, ``plan`` and ``rejections`` set as the platform sets them; a
  **Python stage** may answer any of its outcomes (each is a move of the environment), fail, or
  overrun its budget;
- the **modes chart**, stepped with a ``record`` event for each batch of readings;
- the **fallback switch**, told ``trigger`` and ``clear`` as its triggers come and go;
- the **knowledge**: the probe readings and the Monitor's derived signals that a chart, a rule or
  the mode signal reads, each ranging over the values its comparisons tell apart
  (:func:`signal_values`), within its declared range;
- whether the veto properties vouch (not yet, at the start) and whether the managed system is
  there, which the environment changes.

The legitimacy rules decide a plan whose values are known (a plan chart's) as at run time; a
Python planner's plan may pass them or not. An action reaches its effector as at run time: not
while the fallback holds the effectors (unless it is a fallback action), not while a veto
property does not vouch, not while the managed system is lost, not in a mode its effector does
not allow.

Always checked, besides each chart's built-in problems and the monitors:
``effector_modes`` (no action reaches an effector in a mode it does not allow),
``fallback_engages`` (the fallback engages whenever a trigger holds), ``back_to_idle`` (from
every state reached, the orchestrator can reach ``idle`` again: no iteration is stuck in a
stage).
"""

from __future__ import annotations

import ast
import itertools
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from sismic.model import Statechart

from rasm.platform.block import shared_chart
from rasm.platform.chart_stages import STAGE_OUTCOMES
from rasm.platform.manifest import AppManifest
from rasm.resources import platform_chart, platform_monitors
from rasm.statechart import load_statechart
from rasm.verify.chart import Finding, PropertyVerdict, Verification
from rasm.verify.component import ChartRun, SettableClock, freeze
from rasm.verify.explore import Move, explore
from rasm.verify.past import Record

__all__ = ["APP_CHECKS", "AppSystem", "signal_values", "verify_app"]

APP_CHECKS = {
    "effector_modes": "no effector action in a mode its effector does not allow",
    "fallback_engages": "the fallback engages whenever one of its triggers holds",
    "back_to_idle": "the orchestrator reaches idle again from every state: no iteration is "
    "stuck in a stage",
}

STAGES = ("monitor", "analyse", "plan", "legitimate", "execute")
# the orchestrator's stage states, and the stage each runs
STAGE_STATES = {
    "monitoring": "monitor", "analysing": "analyse", "planning": "plan",
    "legitimating": "legitimate", "executing": "execute",
}
# what a Python stage may answer, as the orchestrator's events
PYTHON_OUTCOMES = {
    "monitor": ("monitored",),
    "analyse": ("anomaly", "no_anomaly"),
    "plan": ("planned", "no_plan"),
    "legitimate": ("accepted", "rejected"),
    "execute": ("executed", "dropped"),
}
STAGE_INPUTS = {"knowledge", "time", "iteration", "anomaly", "plan", "rejections"}
_OTHER = "other"  # a string no comparison names
_ABSENT = ("absent",)  # a signal not in knowledge yet
_PLACEHOLDER = {"float": 0.0, "int": 0, "bool": False, "str": "", "json": []}


# ----------------------------------------------------------------------------- knowledge


def _read_key(node: ast.AST, sources: tuple[str, ...]) -> str | None:
    """The key of ``knowledge.get('k')``, ``knowledge['k']``, ``event.data.get('k')`` or
    ``event.data['k']`` (the sources allowed), else None."""
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
        if node.func.attr != "get" or not node.args:
            return None
        owner, key = node.func.value, node.args[0]
    elif isinstance(node, ast.Subscript):
        owner, key = node.value, node.slice
    else:
        return None
    if not (isinstance(key, ast.Constant) and isinstance(key.value, str)):
        return None
    if isinstance(owner, ast.Name) and owner.id in sources:
        return key.value
    if (
        "event.data" in sources and isinstance(owner, ast.Attribute) and owner.attr == "data"
        and isinstance(owner.value, ast.Name) and owner.value.id == "event"
    ):
        return key.value
    return None


def _chart_code(statechart: Statechart) -> Iterable[str]:
    for transition in statechart.transitions:
        for code in (transition.guard, transition.action):
            if code:
                yield code
    for name in statechart.states:
        state = statechart.state_for(name)
        for code in (getattr(state, "on_entry", None), getattr(state, "on_exit", None)):
            if code:
                yield code


def _constant(node: ast.AST, names: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name) and node.id in names:
        return names[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        inner = _constant(node.operand, names)
        if isinstance(inner, int | float) and not isinstance(inner, bool):
            return -inner
    return None


def _chart_reads(
    statechart: Statechart, sources: tuple[str, ...], names: Mapping[str, Any],
    found: dict[str, set[Any]],
) -> None:
    """Add to ``found`` each key the chart reads from ``sources``, with the constants it is
    compared with (``abs(k) < c`` gives ±c)."""
    for code in _chart_code(statechart):
        try:
            tree = ast.parse(code.strip() if "\n" not in code.strip() else code, mode="exec")
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            key = _read_key(node, sources)
            if key is not None:
                found.setdefault(key, set())
            if not isinstance(node, ast.Compare):
                continue
            operands = [node.left, *node.comparators]
            for i, operand in enumerate(operands):
                absolute = False
                inner = operand
                if (
                    isinstance(operand, ast.Call) and isinstance(operand.func, ast.Name)
                    and operand.func.id == "abs" and operand.args
                ):
                    inner, absolute = operand.args[0], True
                key = _read_key(inner, sources)
                if key is None:
                    continue
                for j, other in enumerate(operands):
                    if j == i:
                        continue
                    value = _constant(other, names)
                    if value is None:
                        continue
                    found.setdefault(key, set()).add(value)
                    if absolute and isinstance(value, int | float):
                        found[key].add(-value)


def _rule_reads(rule_sets: Iterable[Any], found: dict[str, set[Any]]) -> None:
    from rasm.properties import ast as A

    for rules in rule_sets:
        model = rules.rules
        for name, variable in model.variables.items():
            if not variable.plan:
                found.setdefault(name, set())
        context = {n for n, v in model.variables.items() if not v.plan}
        for rule in model.rules:
            stack = [e for e in (rule.when, rule.require) if e is not None]
            while stack:
                node = stack.pop()
                if isinstance(node, A.Binary) and node.op in ("<", "<=", ">", ">=", "==", "!="):
                    for a, b in ((node.left, node.right), (node.right, node.left)):
                        if isinstance(a, A.Name) and isinstance(b, A.Literal):
                            if a.name in context:
                                found.setdefault(a.name, set()).add(b.value)
                stack.extend(A.children(node))


def signal_values(kind: str, constants: set[Any], low: float | None, high: float | None) -> list:
    """One value per region that ``constants`` split a signal of type ``kind`` into, within
    [low, high]: each constant, one between two, one below and one above."""
    if kind == "bool":
        return [True, False]
    if kind == "str":
        words = sorted(str(c) for c in constants if isinstance(c, str))
        return [*words, _OTHER]
    if kind not in ("float", "int"):
        return [_PLACEHOLDER.get(kind, None)]
    points = sorted(
        {c for c in constants if isinstance(c, int | float) and not isinstance(c, bool)}
    )
    if not points:
        start = 0 if low is None else low
        return [int(start) if kind == "int" else float(start)]
    below, above = points[0] - 1, points[-1] + 1
    if low is not None and low < points[0]:
        below = max(below, low)
    if high is not None and high > points[-1]:
        above = min(above, high)
    values = [below]
    for a, b in itertools.pairwise(points):
        values += [a, (a + b) / 2 if kind == "float" else (a + b) // 2]
    values += [points[-1], above]
    inside = []
    for v in values:
        if low is not None and v < low:
            continue
        if high is not None and v > high:
            continue
        v = int(v) if kind == "int" else float(v)
        if v not in inside:
            inside.append(v)
    return inside or [low if low is not None else high]


# ----------------------------------------------------------------------------- the system


class AppSystem:
    """The charts of an application bound as ``rasm run`` binds them: see the module docstring."""

    properties: list = []

    def __init__(self, manifest: AppManifest, rule_sets: list[Any]) -> None:
        self.manifest = manifest
        self.rule_sets = rule_sets
        self.clock = SettableClock()
        self.skipped = 0
        self._parts: dict[tuple, tuple] = {}  # distinct parts of the states' keys and snapshots
        self.effectors = manifest.effectors
        chart = manifest.statecharts.get("adaptation_orchestrator") or platform_chart(
            "adaptation_orchestrator"
        )
        self.ao = ChartRun(
            load_statechart(chart), self.clock,
            initial_context={"stage_budget": manifest.stage_budget,
                             "max_replans": manifest.max_replans},
        )
        self.monitors = [
            self.ao.interp.bind_property_statechart(shared_chart(path))._interpreter
            for path in platform_monitors()
        ]
        self.stages: dict[str, ChartRun] = {}
        for stage in STAGES:
            ref = manifest.components.get(stage, "")
            if ref.endswith((".yaml", ".yml")):
                self.stages[stage] = ChartRun(
                    load_statechart(manifest.folder / ref), self.clock, inputs=STAGE_INPUTS
                )
        self.modes = (
            ChartRun(load_statechart(manifest.modes), self.clock, inputs={"knowledge"})
            if manifest.modes else None
        )
        self.fallback = manifest.fallback
        self.fb = None
        if self.fallback is not None:
            path = manifest.statecharts.get("fallback") or platform_chart("fallback")
            self.fb = ChartRun(
                load_statechart(path), self.clock, initial_context={"dwell": self.fallback.dwell}
            )
        self.charts: dict[str, ChartRun] = {"ao": self.ao, **self.stages}
        if self.modes is not None:
            self.charts["modes"] = self.modes
        if self.fb is not None:
            self.charts["fallback"] = self.fb
        self.values, self.kept = self._signal_values()
        self.veto = bool(manifest.veto_properties or manifest.external_verdicts)
        # the state beside the charts: knowledge, whether the veto properties vouch, whether
        # the managed system is there, the iteration in hand, the failed iterations
        self.knowledge: dict[str, Any] = {}
        self.vouched = not self.veto  # fail closed: not judged yet vetoes
        self.online = True
        self.iteration: dict[str, Any] = {}
        self.failures = (0, 0)  # (consecutive failed iterations, clean ones since)
        self.delivered: list[tuple[str, frozenset[str], bool]] = []  # this move's actions
        self.engage_failed: list[str] = []

    # ------------------------------------------------------------------ the knowledge

    def _signal_values(self) -> tuple[dict[str, list[Any]], list[str]]:
        """The values each relevant signal ranges over (see :func:`signal_values`), and the
        signals read from knowledge (the others matter only in the record they come in)."""
        m = self.manifest
        found: dict[str, set[Any]] = {}
        for run in self.stages.values():
            _chart_reads(run.statechart, ("knowledge",), run.context, found)
        if self.modes is not None:
            _chart_reads(self.modes.statechart, ("knowledge",), self.modes.context, found)
        _rule_reads(self.rule_sets, found)
        if m.mode_signal:
            modes = {mode for e in m.effectors.values() for mode in (e.modes or ())}
            found.setdefault(m.mode_signal, set()).update(modes)
        kept = sorted(found)
        if self.modes is not None:
            _chart_reads(self.modes.statechart, ("event.data",), self.modes.context, found)
        kinds: dict[str, tuple[str, float | None, float | None]] = {}
        for probe in m.probes:
            for name, signal in probe.signals.items():
                kinds[name] = (signal.type, signal.minimum, signal.maximum)
        for name, kind in m.produces.get("monitor", {}).items():
            kinds.setdefault(name, (kind, None, None))
        values = {
            name: signal_values(*kinds[name][:1], constants, *kinds[name][1:])
            for name, constants in sorted(found.items()) if name in kinds
        }
        return values, kept

    def _readings(self) -> list[tuple[str, tuple[tuple[str, Any], ...]]]:
        """Each probe's relevant signals, every combination of their values."""
        out = []
        for probe in self.manifest.probes:
            names = [n for n in probe.signals if n in self.values]
            if not names:
                continue
            for combo in itertools.product(*(self.values[n] for n in names)):
                out.append((probe.topic, tuple(zip(names, combo, strict=True))))
        return out

    def _derived(self) -> list[tuple[tuple[str, Any], ...]]:
        """The Monitor's derived signals a Python monitor may return, every combination."""
        names = [n for n in self.manifest.produces.get("monitor", {}) if n in self.values]
        return [
            tuple(zip(names, combo, strict=True))
            for combo in itertools.product(*(self.values[n] for n in names))
        ]

    # ------------------------------------------------------------------ System

    def start(self) -> tuple[list[Record], list[tuple[str, str]], bool]:
        failures: list[tuple[str, str]] = []
        records: list[Record] = []
        for name, run in self.charts.items():
            steps, failed, stable = run.execute()
            failures += [(k, f"{name}: {m}") for k, m in failed]
            if name in ("ao", "fallback"):
                for event in ("configure", "configuration_done", "initialization_done"):
                    run.queue(event)
                    more, failed, stable = run.execute()
                    failures += [(k, f"{name}: {m}") for k, m in failed]
        if self.modes is not None:
            self.modes.context["knowledge"] = dict(self.knowledge)
        records.append(self._record(None))
        self._evaluate_fallback()
        return records, failures, True

    def key(self) -> tuple:
        # the parts of a state's key repeat from state to state (a chart that did not move):
        # each distinct part is kept once, and the keys of the states share it
        share = self._parts.setdefault
        charts = tuple(share(key, key) for key in (run.key() for run in self.charts.values()))
        monitors = tuple(share(key, key) for key in map(_monitor_key, self.monitors))
        knowledge = tuple((k, freeze(self.knowledge.get(k, _ABSENT))) for k in self.kept)
        return (
            share(charts, charts), share(monitors, monitors), share(knowledge, knowledge),
            self.vouched, self.online, freeze(self.iteration), self.failures,
        )

    def save(self) -> Any:
        # the snapshots of the charts and monitors repeat from state to state too: each
        # distinct one is kept once (those holding a mutable value are kept as they are)
        share = self._share
        return (
            self.clock.now_ns, tuple(share(run.save()) for run in self.charts.values()),
            tuple(share(_save_monitor(m)) for m in self.monitors),
            dict(self.knowledge), self.vouched, self.online, dict(self.iteration), self.failures,
        )

    def _share(self, snapshot: tuple, depth: int = 1) -> Any:
        try:
            return self._parts.setdefault(snapshot, snapshot)
        except TypeError:  # a mutable value in it: its other parts are kept once
            if depth and type(snapshot) is tuple:
                return tuple(
                    self._share(part, 0) if type(part) in (tuple, frozenset) else part
                    for part in snapshot
                )
            return snapshot

    def restore(self, snapshot: Any) -> None:
        (now, charts, monitors, knowledge, self.vouched, self.online, iteration,
         self.failures) = snapshot
        self.clock.set(now)
        for run, snap in zip(self.charts.values(), charts, strict=True):
            run.restore(snap)
        for interp, snap in zip(self.monitors, monitors, strict=True):
            _restore_monitor(interp, snap)
        self.knowledge = dict(knowledge)
        self.iteration = dict(iteration)

    def configuration(self) -> frozenset[str]:
        return frozenset(
            f"{name}:{state}" for name, run in self.charts.items() for state in run.configuration
        )

    def final(self) -> bool:
        return False

    def entered(self) -> set[str]:
        return {f"{name}:{s}" for name, run in self.charts.items() for s in run.entered}

    def ignored_record(self, move: Move) -> Record | None:
        return None

    def idle(self) -> bool:
        return "idle" in self.ao.configuration or "suspended" in self.ao.configuration

    def pending_stage(self) -> str | None:
        for state, stage in STAGE_STATES.items():
            if state in self.ao.configuration:
                return stage
        return None

    def moves(self, *, skip_ignored: bool) -> list[Move]:
        now = self.clock.now_ns
        stage = self.pending_stage()
        out: list[Move] = []
        if stage is not None and stage not in self.stages:  # a Python stage: its answers
            for outcome in self._answers(stage):
                data = ()
                if stage == "monitor" and outcome == "monitored":
                    for derived in self._derived():
                        out.append(Move(now, f"{stage}:{outcome}", derived))
                    continue
                out.append(Move(now, f"{stage}:{outcome}", data))
            out.append(Move(now, f"{stage}:stage_failed"))
        elif stage is None:
            out.append(Move(now, "tick"))
            for topic, values in self._readings():
                out.append(Move(now, f"reading {topic}", values))
            if self.veto:
                out.append(Move(now, "veto vouches" if not self.vouched else "veto violated"))
            if self.fallback is not None and "managed_system_lost" in self.fallback.when:
                out.append(Move(now, "managed system lost" if self.online else
                                "managed system back"))
        due = [d for d in (run.next_deadline() for run in self.charts.values()) if d is not None]
        due = [d for d in due if d > now]
        if due:
            out.append(Move(min(due)))
        return out

    def _answers(self, stage: str) -> list[str]:
        outcomes = list(PYTHON_OUTCOMES[stage])
        if stage == "execute":
            if not any(self._deliverable(name, kind="adaptation") for name in self.effectors):
                outcomes.remove("executed")
        return outcomes

    def apply(self, move: Move) -> tuple[list[Record], list[tuple[str, str]], bool]:
        self.delivered = []
        self.engage_failed = []
        failures: list[tuple[str, str]] = []
        if move.time_ns != self.clock.now_ns:
            self.clock.set(move.time_ns)
        name = move.event
        if name is None:  # the clock: the timers due fire
            for run_name, run in self.charts.items():
                failures += self._run(run_name, run)
            failures += self._drive()
        elif name == "tick":
            self._evaluate_fallback()
            self.ao.queue("tick")
            failures += self._drive()
        elif name.startswith("reading "):
            self.knowledge.update(dict(move.data))
            if self.modes is not None:
                self.modes.context["knowledge"] = dict(self.knowledge)
                self.modes.queue("record", dict(move.data))
                failures += self._run("modes", self.modes)
        elif name in ("veto vouches", "veto violated"):
            self.vouched = name == "veto vouches"
            self._evaluate_fallback()
        elif name in ("managed system lost", "managed system back"):
            self.online = name == "managed system back"
            self.ao.queue("managed_system_back" if self.online else "managed_system_lost")
            failures += self._run("ao", self.ao)
            self._evaluate_fallback()
            failures += self._drive()
        else:  # a Python stage's answer
            stage, outcome = name.split(":", 1)
            if stage == "monitor" and move.data:
                self.knowledge.update(dict(move.data))
            failures += self._answer(stage, outcome, {})
            failures += self._drive()
        return [self._record(move)], failures, True

    def _record(self, move: Move | None) -> Record:
        return Record(
            time_ns=self.clock.now_ns,
            configuration=self.configuration(),
            received=None if move is None else move.event,
            sent=frozenset(),
            context={},
            transitions=True,
        )

    # ------------------------------------------------------------------ the driver

    def _run(self, name: str, run: ChartRun) -> list[tuple[str, str]]:
        steps, failed, stable = run.execute()
        out = [(kind, f"{name}: {message}") for kind, message in failed]
        if not stable:
            out.append(("no stable state", f"{name}: more than 10000 macro steps without an event"))
        if name == "ao":
            for step in steps:
                for event, _ in step.sent:
                    if event in ("adaptation_cancelled", "stage_timeout"):
                        self.iteration["failed"] = True
                if step.configuration & {"idle", "suspended"} and self.iteration.get("started"):
                    self._iteration_ended()
                if "monitoring" in step.configuration and not self.iteration.get("started"):
                    self.iteration = {"started": True, "rejections": 0}
        return out

    def _iteration_ended(self) -> None:
        """Count the iteration for the stage_failures trigger, as FailedIterations does."""
        it = self.iteration
        consecutive, clean = self.failures
        counted = self.fallback is not None and "stage_failures" in self.fallback.when
        threshold = self.fallback.after_failures if counted else 0
        failed = it.get("failed", False)
        no_plan = it.get("anomaly") is not None and not it.get("ended") and not failed
        if failed or no_plan:
            consecutive, clean = min(consecutive + 1, threshold), 0
        else:
            clean = min(clean + 1, threshold)
            if it.get("ended") or (consecutive >= threshold and clean >= threshold):
                consecutive = 0
        if consecutive < threshold:
            clean = 0  # counted only while the trigger holds (to release it): not state before
        self.failures = (consecutive, clean) if threshold else (0, 0)
        self.iteration = {}

    def _drive(self) -> list[tuple[str, str]]:
        """Step the orchestrator until it waits: idle, or a Python stage in hand."""
        failures = self._run("ao", self.ao)
        for _ in range(100):
            stage = self.pending_stage()
            if stage is None or stage not in self.stages or self.iteration.get("asked") == stage:
                return failures
            self.iteration["asked"] = stage
            failures += self._ask_chart(stage)
        return failures

    def _ask_chart(self, stage: str) -> list[tuple[str, str]]:
        run = self.stages[stage]
        it = self.iteration
        run.context.update(
            knowledge=dict(self.knowledge), time=self.clock.time, iteration=1,
            anomaly=it.get("anomaly"), plan=it.get("plan"), rejections=it.get("rejections", 0),
        )
        run.queue(stage)
        steps, failed, stable = run.execute()
        failures = [(kind, f"{stage} chart: {message}") for kind, message in failed]
        sent = [(event, data) for step in steps for event, data in step.sent]
        answers = [(e, d) for e, d in sent if e in STAGE_OUTCOMES[stage]]
        if failed or not stable:
            return failures + self._answer(stage, "stage_failed", {})
        if not answers:
            return failures + self._answer(stage, "timeout", {})
        if stage == "execute":
            actions = [d for e, d in answers if e == "action"]
            return failures + self._answer(stage, "actions", {"actions": actions})
        event, data = answers[0]
        return failures + self._answer(stage, event, data)

    def _answer(self, stage: str, outcome: str, data: dict[str, Any]) -> list[tuple[str, str]]:
        """Post ``stage``'s outcome to the orchestrator, as its driver does."""
        it = self.iteration
        if outcome == "timeout":
            # no answer: as an overrun, the chart's after(stage_budget) ends the iteration
            it["failed"] = True
            return []
        it.pop("asked", None)
        if outcome == "stage_failed":
            it["failed"] = True
            self.ao.queue("stage_failed", {"stage": stage, "reason": "verify"})
            return self._run("ao", self.ao)
        event = outcome
        if stage == "analyse" and outcome == "anomaly":
            it["anomaly"] = {k: v for k, v in data.items()} if data else {"reason": "?"}
        if stage == "plan" and outcome == "planned":
            it["plan"] = dict(data) if stage in self.stages else None
        if stage == "legitimate":
            event = self._legitimate(outcome)
            if event == "rejected":
                it["rejections"] = it.get("rejections", 0) + 1
        if stage == "execute":
            if outcome == "actions":
                delivered = [
                    self._deliver(str(a.get("effector")), "adaptation")
                    for a in data.get("actions", [])
                ]
                event = "executed" if any(delivered) else "dropped"
            elif outcome == "executed":
                # a Python Execute: one action that reached an effector it could reach
                name = next(n for n in self.effectors if self._deliverable(n, "adaptation"))
                self._deliver(name, "adaptation")
            it["ended"] = True
        self.ao.queue(event)
        return self._run("ao", self.ao)

    def _legitimate(self, outcome: str) -> str:
        """The Legitimate stage's verdict with the rules: a known plan they break is
        rejected, whatever the stage said."""
        plan = self.iteration.get("plan")
        if plan is not None and outcome == "accepted":
            for rules in self.rule_sets:
                if not rules.evaluate(plan, dict(self.knowledge)).accepted:
                    return "rejected"
        return outcome

    def _mode(self) -> set[Any]:
        if self.modes is not None:
            return set(self.modes.configuration)
        signal = self.manifest.mode_signal
        return {self.knowledge.get(signal)} if signal else set()

    def _deliverable(self, effector: str, kind: str) -> bool:
        """Whether an action would reach ``effector`` now: the path of every action."""
        spec = self.effectors.get(effector)
        if spec is None or not self.online:
            return False
        if kind != "fallback":
            if self.fb is not None and "nominal" not in self.fb.configuration:
                return False
            if not self.vouched:
                return False
        if spec.modes is not None and not self._mode().intersection(spec.modes):
            return False
        return True

    def _deliver(self, effector: str, kind: str) -> bool:
        ok = self._deliverable(effector, kind)
        if ok:
            spec = self.effectors[effector]
            mode = frozenset(str(m) for m in self._mode())
            allowed = spec.modes is None or bool(mode.intersection(spec.modes))
            self.delivered.append((effector, mode, allowed))
        return ok

    def _triggers(self) -> list[str]:
        if self.fallback is None:
            return []
        when = self.fallback.when
        held = []
        if "managed_system_lost" in when and not self.online:
            held.append("managed_system_lost")
        if "stage_failures" in when and self.failures[0] >= self.fallback.after_failures:
            held.append("stage_failures")
        if "veto" in when and not self.vouched:
            held.append("veto")
        return held

    def _evaluate_fallback(self) -> None:
        """FallbackSwitch.evaluate: tell the chart, and send the fallback actions."""
        if self.fb is None:
            return
        held = self._triggers()
        config = self.fb.configuration
        if held and ("nominal" in config or "recovering" in config):
            was_nominal = "nominal" in config
            self.fb.queue("trigger", {"reason": ", ".join(held)})
            self.fb.execute()
            if was_nominal and "fallback" in self.fb.configuration:
                for effector in self.fallback.actions:
                    self._deliver(effector, "fallback")
        elif not held and "fallback" in config:
            self.fb.queue("clear")
            self.fb.execute()
        if held and "fallback" not in self.fb.configuration:
            self.engage_failed = held

    def checks(self, records: list[Record], move: Move | None) -> list[tuple[str, str]]:
        found = []
        for effector, mode, allowed in self.delivered:
            if not allowed:
                found.append(("effector_modes", f"an action reached {effector} in mode "
                              f"{', '.join(sorted(mode))}"))
        if self.engage_failed:
            found.append(("fallback_engages", "the fallback did not engage although "
                          f"{', '.join(self.engage_failed)} held"))
        return found


def _monitor_key(interp: Any) -> tuple:
    return (frozenset(interp._configuration),
            tuple(sorted((k, freeze(v)) for k, v in interp._evaluator._context.items())))


def _save_monitor(interp: Any) -> tuple:
    # immutable parts, as ChartRun.save's (the context's values are not copied: restored as
    # they were saved)
    return (interp._initialized, interp._time, frozenset(interp._configuration),
            tuple(interp._entry_time.items()), tuple(interp._idle_time.items()),
            tuple(interp._evaluator._context.items()), tuple(interp._internal_queue),
            tuple(interp._external_queue))


def _restore_monitor(interp: Any, snap: tuple) -> None:
    (interp._initialized, interp._time, configuration, entry, idle, context, internal,
     external) = snap
    interp._configuration = set(configuration)
    interp._entry_time = dict(entry)
    interp._idle_time = dict(idle)
    interp._evaluator._context.clear()
    interp._evaluator._context.update(context)
    interp._internal_queue = list(internal)
    interp._external_queue = list(external)


def load_app(app: str | Path) -> AppSystem:
    """The system of the app at ``app`` (its folder or manifest)."""
    from rasm.platform.manifest import load_manifest
    from rasm.platform.signals import check_app
    from rasm.rules.engine import RuleSet

    manifest = load_manifest(app)
    check_app(manifest)  # what rasm run refuses at start-up is refused here too (exit 2)
    rules = [RuleSet.load(path, plan_fields=manifest.plan_fields) for path in manifest.rules]
    return AppSystem(manifest, rules)


def verify_app(app: str | Path, *, max_states: int = 100_000) -> Verification:
    """``rasm verify APP``: explore the app's charts bound together; the checks of
    :data:`APP_CHECKS` are its properties (see :func:`rasm.verify.chart.verify_chart`)."""

    system = load_app(app)
    found = explore(
        system, max_states=max_states, goal=system.idle,
        goal_problem=("back_to_idle", "the orchestrator cannot reach idle again"),
    )
    by_check: dict[str, Any] = {}
    problems = []
    for problem in found.problems:
        if problem.kind in APP_CHECKS:
            by_check.setdefault(problem.kind, problem)
        else:
            problems.append(Finding(problem.kind, problem.message, _app_counterexample(problem)))
    properties = []
    for name in APP_CHECKS:
        problem = by_check.get(name)
        if problem is not None:
            cex = _app_counterexample(problem)
            cex.explanation = [problem.message]
            properties.append(PropertyVerdict(name, "violated", cex))
        else:
            properties.append(
                PropertyVerdict(name, "satisfied" if found.complete else "inconclusive")
            )
    unreachable: list[str] = []
    if found.complete:  # the app's own charts: a state no run enters is dead code, or a bug
        own = {name: run for name, run in system.charts.items() if name not in ("ao", "fallback")}
        for name, run in own.items():
            for state in sorted(set(run.statechart.states) - run.entered):
                unreachable.append(f"{name}:{state}")
                problems.append(Finding(
                    "unreachable", f"state {state!r} of the {name} chart is entered on no path"
                ))
    if problems or any(p.verdict == "violated" for p in properties):
        verdict = "violated"
    else:
        verdict = "satisfied" if found.complete else "inconclusive"
    return Verification(
        chart=str(app), verdict=verdict, complete=found.complete, states=found.states,
        transitions=found.transitions,
        reachable=sorted(sorted(conf) for conf in found.configurations),
        unreachable=unreachable, properties=properties, problems=problems,
        environment="ticks, readings, veto verdicts and the managed system coming and going; "
        "each Python stage's outcomes; the clock advancing to each next deadline",
        max_states=max_states,
    )


def _app_counterexample(problem: Any) -> Any:
    from rasm.verify.chart import Counterexample

    return Counterexample(list(problem.path or []), [])
