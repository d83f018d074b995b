"""The building blocks of seed §5, each a :class:`~rasm.platform.block.Block` driven by its chart.

The low-frequency paths (an action through Adaptation Manager, Trustworthiness Manager and
Trustworthiness Checker; persistence batches) step the block's chart through its core-task
sub-states. The per-record paths (Telegraf digesting, knowledge registration, logging) are gated by
the block's mode (no work unless ``initialized``) but do not step a chart per record: a chart step
costs tens of microseconds, a record must cost less (docs/runtime.md).
"""

from __future__ import annotations

import logging
import math
import sys
from collections import Counter, defaultdict, deque
from collections.abc import Callable, Mapping
from typing import Any

from rasm.errors import PlatformError
from rasm.knowledge.base import EXACT_CLASS, register_each
from rasm.platform.block import Block
from rasm.platform.components import Action, Plan
from rasm.platform.manifest import Effector, Probe, Signal
from rasm.properties.monitor import Verdict
from rasm.properties.outcome import PropertyOutcome

__all__ = [
    "AdaptationManager",
    "CommunicationManager",
    "KnowledgeManager",
    "LoggingAndTracking",
    "StateManager",
    "StorageManager",
    "Telegraf",
    "TrustworthinessChecker",
    "TrustworthinessManager",
]

_telegraf_log = logging.getLogger("rasm.telegraf")
_tc_log = logging.getLogger("rasm.tc")

_TYPES: dict[str, tuple[type, ...]] = {
    "float": (float, int),
    "int": (int,),
    "bool": (bool,),
    "str": (str,),
}


class _BusHandler(logging.Handler):
    """Publishes log records on a bus topic; never recurses into itself."""

    def __init__(self, publish: Callable[[dict[str, Any]], Any]) -> None:
        super().__init__()
        self.publish = publish
        self._busy = False

    def emit(self, record: logging.LogRecord) -> None:
        if self._busy:
            return
        self._busy = True
        try:
            self.publish(
                {
                    "level": record.levelname,
                    "logger": record.name,
                    "message": record.getMessage(),
                    "created": record.created,
                }
            )
        except Exception:  # a broken bus must not break logging
            pass
        finally:
            self._busy = False


class _CountingHandler(logging.Handler):
    """Counts records per severity (handlers see what child loggers propagate; filters don't)."""

    def __init__(self, counts: Counter[str]) -> None:
        super().__init__()
        self.counts = counts

    def emit(self, record: logging.LogRecord) -> None:
        self.counts[record.levelname] += 1


class LoggingAndTracking(Block):
    """Logging and Tracking (lt): severities and sinks on the standard ``logging`` module.

    ``sinks`` are ``console`` (standard error), ``file:PATH`` and ``bus:TOPIC`` (each record
    published as ``{"level", "logger", "message", "created"}``). The sinks are attached to the
    ``rasm`` logger while the block is initialised, so every platform module's records reach them.
    """

    chart_name = "logging_and_tracking"
    short_name = "lt"

    def __init__(
        self,
        *,
        level: int = logging.WARNING,
        sinks: tuple[str, ...] = ("console",),
        publish: Callable[[str, dict[str, Any]], Any] | None = None,
        logger: str = "rasm",
        **kw: Any,
    ) -> None:
        self.logger = logging.getLogger(logger)
        self.level = level
        self.sinks = tuple(sinks)
        self.publish = publish
        self.handlers: list[logging.Handler] = []
        self.counts: Counter[str] = Counter()
        super().__init__(**kw)

    def on_configuration(self) -> None:
        for sink in self.sinks:
            kind, _, target = sink.partition(":")
            if kind not in ("console", "file", "bus") or (kind != "console" and not target):
                raise ValueError(f"unknown log sink {sink!r} (console, file:PATH or bus:TOPIC)")

    def on_initialization(self) -> None:
        fmt = logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s")
        for sink in self.sinks:
            kind, _, target = sink.partition(":")
            if kind == "console":
                handler: logging.Handler = logging.StreamHandler()
            elif kind == "file":
                handler = logging.FileHandler(target, encoding="utf-8")
            else:
                publish = self.publish
                if publish is None:
                    continue
                handler = _BusHandler(lambda payload, t=target, p=publish: p(t, payload))
            handler.setLevel(self.level)
            handler.setFormatter(fmt)
            self.logger.addHandler(handler)
            self.handlers.append(handler)
        counter = _CountingHandler(self.counts)
        counter.setLevel(self.level)
        self.logger.addHandler(counter)
        self.handlers.append(counter)
        self.logger.setLevel(min(self.level, self.logger.level or self.level))

    def on_termination(self) -> None:
        for handler in self.handlers:
            self.logger.removeHandler(handler)
            handler.close()
        self.handlers.clear()

    def is_enabled(self, severity: int = logging.INFO) -> bool:
        return self.mode == "initialized" and severity >= self.level

    def log(self, severity: int, message: str, *args: Any, exc_info: Any = None) -> None:
        if self.is_enabled(severity):
            self.logger.log(severity, message, *args, exc_info=exc_info)


class StateManager(Block):
    """State Manager (sm): the mode of every block and the timing history of every stage."""

    __slots__ = ("modes", "nodes", "stage_timing")  # slots, as Block's (read per iteration)

    chart_name = "state_manager"
    short_name = "sm"

    def __init__(self, *, timing_history: int = 1000, **kw: Any) -> None:
        self.modes: dict[str, str] = {}
        self.nodes: dict[str, str] = {}  # remote node -> online | offline | silent (presence)
        self.stage_timing: dict[str, deque[tuple[float, float]]] = defaultdict(
            lambda: deque(maxlen=timing_history)
        )
        super().__init__(**kw)

    def track(self, block: Block) -> None:
        """Follow ``block``'s mode from now on."""
        self.modes[block.name] = block.mode
        block.add_mode_listener(self._mode_changed)

    def _mode_changed(self, block: Block, mode: str) -> None:
        self.modes[block.name] = mode

    def get_time(self) -> float:
        return self.clock.time

    def get_status(self, name: str | None = None) -> Any:
        """The mode of block ``name``, or of every block."""
        return dict(self.modes) if name is None else self.modes.get(name)

    def record_stage(self, stage: str, start: float, duration: float) -> None:
        self.stage_timing[stage].append((start, duration))

    def percentiles(self, stage: str, qs: tuple[float, ...] = (50, 90, 99)) -> dict[str, float]:
        durations = sorted(d for _, d in self.stage_timing.get(stage, ()))
        if not durations:
            return {}
        out = {}
        for q in qs:
            k = max(0, min(len(durations) - 1, math.ceil(q / 100 * len(durations)) - 1))
            out[f"p{q:g}"] = durations[k]
        return out


class KnowledgeManager(Block):
    """Knowledge Manager (km): ``register_knowledge`` / ``read_knowledge`` over the store."""

    __slots__ = ("store",)  # a slot, as Block's (read for every record)

    chart_name = "knowledge_manager"
    short_name = "km"

    def __init__(self, store: Any, **kw: Any) -> None:
        self.store = store
        super().__init__(**kw)

    def register_knowledge(self, key: str, value: Any, time: float | None = None) -> Any:
        if self._mode != "initialized":  # tested inline: this runs for every value stored
            self.require_mode("initialized")
        return self.store.register_knowledge(key, value, self.clock.time if time is None else time)

    def register_values(
        self,
        values: Mapping[str, Any],
        time: float | None = None,
        *,
        into: dict[str, Any] | None = None,
    ) -> dict[str, Exception]:
        """Store each of ``values`` as :meth:`register_knowledge` would, one after the other;
        return the refused ones, ``{key: the error}`` (a refused value does not stop the rest).
        With ``into``, each value stored is put there too, as stored (see
        :meth:`~rasm.knowledge.base.KnowledgeBase.register_values`).
        """
        if self._mode != "initialized":
            try:
                self.require_mode("initialized")
            except PlatformError as exc:
                return dict.fromkeys(values, exc)
        if time is None:
            time = self.clock.time
        store = self.store
        batch = getattr(store, "register_values", None)
        if batch is not None:  # one lock for the batch (KnowledgeBase)
            # a store's own register_values may not know `into`: asked without it when unused
            return batch(values, time) if into is None else batch(values, time, into=into)
        return register_each(store.register_knowledge, values, time, into)

    def read_knowledge(self, key: str, default: Any = None) -> Any:
        return self.store.read_knowledge(key, default)


class StorageManager(Block):
    """Storage Manager (stom): batches knowledge updates and persists them (SQLite, WAL)."""

    chart_name = "storage_manager"
    short_name = "stom"

    def __init__(self, storage: Any, *, flush_period: float = 1.0, **kw: Any) -> None:
        self.storage = storage
        self.persisted = 0
        super().__init__(context={"flush_period": flush_period}, **kw)

    def register_knowledge_update(self, key: str, sample: Any) -> None:
        if self.storage is None:
            return
        self.storage.register_knowledge_update(key, sample)
        if "idle" in self.interpreter._configuration:  # only the first update steps the chart
            self.send("update_registered")

    def on_enter_persisting(self) -> None:
        try:
            self.persisted += self.update_persistency()
        except Exception as exc:  # a full disk must not stop the loop; the chart retries
            logging.getLogger("rasm.platform").error("persisting knowledge failed: %s", exc)
            self.post("persist_failed")
            return
        self.post("persisted")

    def update_persistency(self) -> int:
        return 0 if self.storage is None else int(self.storage.update_persistency() or 0)

    def on_termination(self) -> None:
        if self.storage is not None:
            self.storage.update_persistency()
            self.storage.close()


class CommunicationManager(Block):
    """Communication Manager (cm): publishers and subscribers on one transport (seed §5.5.1).

    The seed's operations (``create_publisher``, ``create_subscriber``, ``publish_message``,
    ``get_queue_message``) come from :class:`rasm.comm.CommunicationManager`; this block adds the
    operation modes: the transport is connected in ``initialization`` and closed on termination,
    and nothing is published unless the block is ``initialized``.
    """

    __slots__ = ("transport", "endpoints")  # slots, as Block's (read for every reading)

    chart_name = "communication_manager"
    short_name = "cm"

    def __init__(self, transport: Any, **kw: Any) -> None:
        from rasm.comm import CommunicationManager as Endpoints

        self.transport = transport
        self.endpoints = Endpoints(transport)
        super().__init__(**kw)

    def on_initialization(self) -> None:
        self.transport.connect()

    def on_termination(self) -> None:
        self.transport.close()

    def create_publisher(self, topic: str, **kw: Any) -> Any:
        return self.endpoints.create_publisher(topic, **kw)

    def create_subscriber(self, topic: str, **kw: Any) -> Any:
        return self.endpoints.create_subscriber(topic, **kw)

    def publish_message(self, topic: str, payload: dict[str, Any]) -> None:
        if self._mode != "initialized":  # tested inline: every probe reading passes here
            self.require_mode("initialized")
        self.transport.publish(topic, payload)

    def subscribe(self, pattern: str, callback: Callable[[Any], Any]) -> Any:
        """Call ``callback(message)`` for every message on ``pattern`` (transport thread)."""
        return self.transport.subscribe(pattern, callback)


class Telegraf(Block):
    """Telegraf (tg): managed-system data into knowledge, by the manifest's routing table.

    Each value is checked against its signal's declared type and range; bad data is logged and
    counted, never stored.
    """

    __slots__ = ("routes", "_plans", "register", "digested", "rejected")  # as Block's

    chart_name = "telegraf"
    short_name = "tg"

    def __init__(
        self, probes: list[Probe], register: Callable[[dict[str, Any], float], Any], **kw: Any
    ) -> None:
        self.routes: dict[str, dict[str, Signal]] = {p.topic: p.signals for p in probes}
        # per topic, what digest() tests each field with (built once: probes are frozen)
        self._plans = {topic: _plan(signals) for topic, signals in self.routes.items()}
        self.register = register
        self.digested = 0
        self.rejected: Counter[str] = Counter()
        super().__init__(**kw)

    def digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """Route one message; returns the values stored (an empty dict if nothing was)."""
        if self._mode != "initialized":
            self.rejected["not running"] += 1
            return {}
        plans = self._plans
        plan = plans[topic] if topic in plans else None  # (no .get method call)
        if plan is None or not isinstance(payload, dict):
            self.rejected["unroutable"] += 1
            return {}
        values: dict[str, Any] = {}
        for key, signal, exact, low, high in plan:
            if key not in payload:
                continue
            value = payload[key]
            cls = type(value)
            if cls is not exact:  # (no attribute lookup for the common value)
                cls = value.__class__  # what an object says it is decides, as it always did
            # the common good value in one test: its exact declared class and in range, which
            # for a float is finite too (see _plan)
            if cls is exact and (low is None or low <= value <= high):
                values[key] = value
                continue
            problem = _check_value(signal, value)
            if problem:
                self.rejected[problem] += 1
                self.logs.log(
                    _telegraf_log,
                    logging.WARNING,
                    f"{topic}: {key} rejected: {problem}",
                    "%s: %s=%r rejected: %s",
                    topic,
                    key,
                    value,
                    problem,
                )
                continue
            values[key] = float(value) if signal.type == "float" else value
        if values:
            self.register(values, time)
            self.digested += 1
        return values


# the range of an int without declared bounds in the fast test; larger ones take the full check
_INT_RANGE = 1 << 1000
_FLOAT_MAX = sys.float_info.max


def _plan(signals: dict[str, Signal]) -> tuple[tuple[str, Signal, Any, Any, Any], ...]:
    """``(field, signal, exact class, low, high)`` per field: the fast test of Telegraf.digest.

    ``low`` is None when the class alone decides (bool, str); numbers need ``low <= value <=
    high``, with the declared bounds or unbounded ones. A float's bounds are within the finite
    floats (an infinite or missing bound is the largest float), so the range test also refuses
    inf, -inf and nan (a nan bound refuses everything): they take the full check, as they did.
    """
    plan = []
    for key, signal in signals.items():
        # an int for a float signal is converted by the full check: only exact classes skip it
        exact = EXACT_CLASS.get(signal.type)
        low, high = signal.minimum, signal.maximum
        if signal.type == "float":
            low = -_FLOAT_MAX if low is None or low < -_FLOAT_MAX else low
            high = _FLOAT_MAX if high is None or high > _FLOAT_MAX else high
        elif signal.type == "int":  # ints are finite; beyond the sentinel the full check fails
            low = -_INT_RANGE if low is None else low
            high = _INT_RANGE if high is None else high
        else:
            low = high = None
        plan.append((key, signal, exact, low, high))
    return tuple(plan)


def _check_value(signal: Signal, value: Any) -> str | None:
    if signal.type == "json":
        return None
    allowed = _TYPES[signal.type]
    if not isinstance(value, allowed) or (signal.type != "bool" and isinstance(value, bool)):
        return f"expected {signal.type}, got {type(value).__name__}"
    if signal.type in ("float", "int"):
        if not math.isfinite(value):
            return "not a finite number"
        if signal.minimum is not None and value < signal.minimum:
            return f"below the declared minimum {signal.minimum}"
        if signal.maximum is not None and value > signal.maximum:
            return f"above the declared maximum {signal.maximum}"
    return None


class TrustworthinessManager(Block):
    """Trustworthiness Manager (tm): ``check_trustworthiness`` of an action (seed §6.4.4).

    An action is trustworthy when its plan was accepted by the Legitimate stage (the loop hands
    over the accepted plans), the rules still accept the plan now, and the Trustworthiness
    Checker vouches for every *veto* property: its latest verdict holds. A veto property whose
    latest verdict is violated, in error or inconclusive, or that has no verdict yet (still in
    warm-up, or a signal it reads never had a value), vetoes the action: fail closed.
    """

    chart_name = "trustworthiness_manager"
    short_name = "tm"

    def __init__(
        self,
        *,
        rules: list[Any],
        veto_properties: tuple[str, ...],
        verdicts: Callable[[], Mapping[str, Verdict]],
        context: Callable[[], dict[str, Any]],
        waiting_for: Callable[[str], tuple[str, ...]] = lambda name: (),
        **kw: Any,
    ) -> None:
        self.rules = rules
        self.veto_properties = veto_properties
        self.verdicts = verdicts  # the latest verdict of each property
        self.waiting_for = waiting_for  # the signals a property not judged yet waits for
        self.context_of = context
        self.accepted_plans: dict[str, Plan] = {}
        self._evidence: tuple[Action, Plan | None] | None = None
        self._verdict: tuple[bool, str] = (False, "not checked")
        super().__init__(**kw)

    def check_trustworthiness(self, action: Action) -> tuple[bool, str]:
        """Return (trustworthy, explanation); fail closed when the block is not running."""
        if self.mode != "initialized":
            return False, f"trustworthiness manager is {self.mode}"
        self._evidence = (action, self.accepted_plans.get(action.plan))
        self._verdict = (False, "check did not complete in time")
        self.send("check_requested")
        return self._verdict

    def on_enter_gathering_evidence(self) -> None:
        self.post("evidence_gathered")

    def on_enter_evaluating(self) -> None:
        action, plan = self._evidence or (None, None)
        ok, why = self._evaluate(action, plan)
        self._verdict = (ok, why)
        self.post("trustworthy" if ok else "untrustworthy")

    def _evaluate(self, action: Action | None, plan: Plan | None) -> tuple[bool, str]:
        if action is None or plan is None:
            return False, "the action's plan was never accepted by the Legitimate stage"
        context = self.context_of()
        for rules in self.rules:
            decision = rules.evaluate(plan.values, context)
            if not decision.accepted:
                return False, f"rules no longer accept the plan: {decision.explanation()}"
            # Execute may put other values in the action than the plan had: the rules judge
            # what is actually sent (payload values win over the plan's of the same name)
            sent = {**plan.values, **action.payload}
            if sent != plan.values:
                decision = rules.evaluate(sent, context)
                if not decision.accepted:
                    return False, f"rules do not accept the action: {decision.explanation()}"
        verdicts = self.verdicts()
        vetoes = [self._veto(name, verdicts.get(name)) for name in self.veto_properties]
        vetoes = [why for why in vetoes if why is not None]
        if vetoes:
            return False, "; ".join(vetoes)
        if self.veto_properties:
            return True, "plan accepted by Legitimate, rules hold, every veto property holds"
        return True, "plan accepted by Legitimate, rules hold"

    def _veto(self, name: str, verdict: Verdict | None) -> str | None:
        """Why veto property ``name`` stops the action, or None when it holds."""
        if verdict is None:
            waits = self.waiting_for(name)
            if waits:
                return f"veto property {name} not judged yet: no value for {', '.join(waits)}"
            return f"veto property {name} not judged yet: no verdict decided so far"
        if verdict.error is not None:
            return f"veto property {name} in error at t={verdict.time:g}: {verdict.error}"
        if verdict.value is False:
            return f"veto property {name} violated at t={verdict.time:g}"
        if verdict.value is None:
            return f"veto property {name} inconclusive at t={verdict.time:g}"
        return None


class AdaptationManager(Block):
    """Adaptation Manager (am): ``perform_adaptation`` / ``perform_diagnosis`` (seed §6.4.4).

    Has the Trustworthiness Manager check the action; when trustworthy, registers it with the
    Trustworthiness Checker, which alone hands it to the effector. Otherwise the action is dropped.
    """

    chart_name = "adaptation_manager"
    short_name = "am"

    def __init__(self, tm: TrustworthinessManager, tc: TrustworthinessChecker, **kw: Any) -> None:
        self.tm = tm
        self.tc = tc
        self._action: Action | None = None
        self._outcome: tuple[bool, str] = (False, "")
        self.last_trusted = False
        super().__init__(**kw)

    def perform_adaptation(self, action: Action) -> tuple[bool, str]:
        """Check and register ``action``; (True, why) when it reached the effector."""
        self.last_trusted = False
        if self.mode != "initialized":
            return False, f"adaptation manager is {self.mode}"
        self._action = action
        self._outcome = (False, "the adaptation did not complete in time")
        self.send("action_requested")
        return self._outcome

    def perform_diagnosis(self, action: Action) -> tuple[bool, str]:
        return self.perform_adaptation(
            Action(action.effector, action.payload, action.plan, "diagnosis")
        )

    def on_enter_checking_trustworthiness(self) -> None:
        ok, why = self.tm.check_trustworthiness(self._action)
        self.last_trusted = ok
        self._outcome = (False, why)
        self.post("trustworthy" if ok else "untrustworthy")

    def on_enter_registering(self) -> None:
        ok, why = self.tc.register_action(self._action)
        self._outcome = (ok, why)
        self.post("registered" if ok else "registration_refused")

    def on_enter_dropping(self) -> None:
        self.post("dropped")


class TrustworthinessChecker(Block):
    """Trustworthiness Checker (tc): ``register_action`` and the online property monitors.

    The only path to an effector: an action is sent when it is applicable in the managed
    system's current mode (and its effector is known). The online monitors of the app's and the
    platform's properties run over every record of the loop (:meth:`observe`): ``latest`` holds
    each property's latest verdict, ``outcomes`` counts them all (its state is the property's
    overall verdict so far). A monitor that raises on a record makes every property it checks
    ``error`` for that record: the checker cannot vouch for them there, and says so.
    """

    chart_name = "trustworthiness_checker"
    short_name = "tc"

    def __init__(
        self,
        *,
        monitors: list[Any],
        effectors: dict[str, Effector],
        send: Callable[[Effector, Action], Any],
        mode_of: Callable[[], str | None],
        on_verdict: Callable[[Verdict], Any] | None = None,
        observers: list[Callable[[Verdict], Any]] | None = None,
        online: Callable[[], bool] = lambda: True,
        **kw: Any,
    ) -> None:
        self.online = online
        self.monitors = monitors
        self.effectors = effectors
        self.send_to_effector = send
        self.mode_of = mode_of
        self.on_verdict = on_verdict
        # called with every verdict, like on_verdict; the list is the caller's and is read at
        # each record, so observers may come and go during a run
        self.observers: list[Callable[[Verdict], Any]] = [] if observers is None else observers
        # the latest verdict of each property; _decided_on: the step (a record, or the end)
        # that decided it
        self.latest: dict[str, Verdict] = {}
        self._decided_on: dict[str, int] = {}
        self._steps = 0
        self.outcomes: dict[str, PropertyOutcome] = {
            name: PropertyOutcome(name) for monitor in monitors for name in monitor.properties
        }
        self.records = 0
        self.monitor_failures = 0  # records on which a monitor raised
        self._failing: dict[Any, int] = {}  # monitor -> records it failed on since it last worked
        self._action: Action | None = None
        self._outcome: tuple[bool, str] = (False, "")
        super().__init__(**kw)

    def observe(self, time: float, record: dict[str, Any]) -> list[Verdict]:
        """Feed one loop record to every monitor; returns the verdicts it decided."""
        index = self.records
        self.records += 1
        self._steps += 1
        decided: list[Verdict] = []
        for monitor in self.monitors:
            try:
                verdicts = monitor.step(time, record)
            except Exception as exc:
                verdicts = self._failed(monitor, index, time, exc)
            else:
                if monitor in self._failing:
                    self._recovered(monitor, time)
            for verdict in verdicts:
                self._take(verdict)
            decided += verdicts
        return decided

    def finish(self) -> list[Verdict]:
        """The end of the run: settle every monitor (``None``: the run ended before a verdict
        could be decided) and name the signals each property never judged waits for."""
        self._steps += 1
        decided: list[Verdict] = []
        for monitor in self.monitors:
            try:
                verdicts = monitor.finish()
            except Exception as exc:
                verdicts = self._failed(monitor, self.records, self.clock.time, exc)
            for verdict in verdicts:
                self._take(verdict)
            decided += verdicts
        for name, outcome in self.outcomes.items():
            if not outcome.judged:
                outcome.missing = self.missing(name)
        return decided

    def missing(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` waits for (none once it has started, or when its
        monitor cannot tell)."""
        for monitor in self.monitors:
            if name in monitor.properties:
                waits = getattr(monitor, "missing", None)
                return tuple(waits(name)) if waits is not None else ()
        return ()

    def _take(self, verdict: Verdict) -> None:
        name = verdict.property
        outcome = self.outcomes.get(name)
        if outcome is None:  # a monitor of another kind may decide about a name it did not list
            outcome = self.outcomes[name] = PropertyOutcome(name)
        outcome.add(verdict.value, verdict.error)
        # a record may decide several verdicts of a bounded-future property, in no particular
        # order: the latest is the worst of those the newest deciding record gave
        if self._decided_on.get(name) != self._steps or _rank(verdict) > _rank(self.latest[name]):
            self.latest[name] = verdict
            self._decided_on[name] = self._steps
        if self.on_verdict is not None:
            self.on_verdict(verdict)
        for observer in self.observers:
            observer(verdict)

    def _failed(self, monitor: Any, index: int, time: float, exc: Exception) -> list[Verdict]:
        """Every property of ``monitor`` in error for this record; the first failure of a run
        of them is logged with its traceback, the rest counted."""
        self.monitor_failures += 1
        why = f"the monitor raised {type(exc).__name__}: {exc}"
        failed = self._failing.get(monitor, 0)
        self._failing[monitor] = failed + 1
        if not failed:
            logging.getLogger("rasm.tc").error(
                "monitor of %s failed at t=%g: %s; its properties (%s) are in error until it "
                "works again",
                _origin(monitor), time, why, ", ".join(monitor.properties), exc_info=exc,
            )
        return [Verdict(name, index, time, False, why) for name in monitor.properties]

    def _recovered(self, monitor: Any, time: float) -> None:
        failed = self._failing.pop(monitor)
        logging.getLogger("rasm.tc").warning(
            "monitor of %s works again at t=%g, after failing on %d record(s)",
            _origin(monitor), time, failed,
        )

    def register_action(self, action: Action | None) -> tuple[bool, str]:
        if self.mode != "initialized" or action is None:
            return False, f"trustworthiness checker is {self.mode}"
        self._action = action
        self._outcome = (False, "registration did not complete")
        self.send("register_requested")
        return self._outcome

    def on_enter_checking_action(self) -> None:
        action = self._action
        effector = self.effectors.get(action.effector) if action else None
        if action is None or effector is None:
            self._outcome = (False, f"unknown effector {action.effector if action else None!r}")
            self.post("action_refused")
            return
        if not self.online():
            self._outcome = (False, "the managed system is offline")
            self.post("action_refused")
            return
        mode = self.mode_of()
        if effector.modes is not None and mode not in effector.modes:
            self._outcome = (False, f"not applicable in managed-system mode {mode!r}")
            self.post("action_refused")
            return
        try:
            self.send_to_effector(effector, action)
        except Exception as exc:
            self._outcome = (False, f"effector unreachable: {exc}")
            self.post("action_refused")
            return
        self._outcome = (True, f"sent to {effector.name} on {effector.topic}")
        self.post("action_registered")


def _rank(verdict: Verdict) -> int:
    """How bad a verdict is for the checker's trust: error, false, inconclusive, true."""
    if verdict.error is not None:
        return 3
    return {False: 2, None: 1, True: 0}[verdict.value]


def _origin(monitor: Any) -> str:
    """The property file a monitor checks, for a log line."""
    spec = getattr(monitor, "spec", None)
    return getattr(spec, "source", None) or type(monitor).__name__
