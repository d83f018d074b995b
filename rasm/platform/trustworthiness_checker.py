"""Trustworthiness Checker: the online property monitors and the only path to an effector."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import Any, Protocol

from rasm.loop import robustness_key
from rasm.platform.action_outcome import ActionOutcome
from rasm.platform.block import Block
from rasm.platform.components import Action
from rasm.platform.manifest import Effector
from rasm.properties.monitor import Verdict
from rasm.properties.outcome import PropertyOutcome, Untested
from rasm.times import format_seconds

__all__ = ["AntecedentWatch", "PropertyMonitor", "TrustworthinessChecker", "written_robustness"]

_log = logging.getLogger("rasm.tc")


class PropertyMonitor(Protocol):
    """What the checker runs over the loop's records: compiled properties
    (:func:`rasm.properties.compile_properties`)."""

    @property
    def properties(self) -> list[str]:
        """The names of the properties it decides."""

    def step(self, time: float, values: Mapping[str, object]) -> list[Verdict]:
        """Take one record; return the verdicts it decided."""

    def finish(self) -> list[Verdict]:
        """The end of the trace: the verdicts still open."""

    def missing(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` still waits for."""


class AntecedentWatch(Protocol):
    """What tells a property satisfied vacuously (:class:`rasm.properties.vacuity.Vacuity`):
    fed the same records as the monitors, it names the antecedents that never held."""

    def step(self, time: float, values: Mapping[str, object]) -> None:
        """Take one record."""

    def finish(self) -> None:
        """The end of the trace."""

    def vacuous(self, name: str) -> tuple[Untested, ...]:
        """The antecedents of property ``name`` that have not held on a judged record."""


class TrustworthinessChecker(Block):
    """Trustworthiness Checker (tc): ``register_action`` and the online property monitors.

    The only path to an effector: an action is sent when it is applicable in the managed
    system's current mode (and its effector is known). ``mode_of`` gives that mode: a value of
    the mode signal, or the active states of the app's modes chart. The online monitors of the
    app's and the platform's properties run over every record of the loop (:meth:`observe`):
    ``latest`` holds each property's latest verdict, ``outcomes`` counts them all (its state is
    the property's overall verdict so far). A monitor that raises on a record makes every
    property it checks ``error`` for that record: the checker cannot vouch for them there, and
    says so. So is a property that reads a stale signal (:meth:`set_stale`): while the signal
    is stale, its verdicts are errors naming it, not judgements of the last reading.
    ``vacuity`` watches the antecedents of the properties' ``->``: at the end, each outcome
    names those that never held (``vacuous``).

    ``write_robustness``, if given, is called once per record with the robustness values
    (SPEC §12) that record's verdicts changed, ``{robustness_<property>: value}``
    (:func:`written_robustness` says which value), and the record's time.
    """

    chart_name = "trustworthiness_checker"
    short_name = "tc"

    def __init__(
        self,
        *,
        monitors: list[PropertyMonitor],
        effectors: dict[str, Effector],
        send: Callable[[Effector, Action], Any],
        mode_of: Callable[[], str | Collection[str] | None],
        observers: list[Callable[[Verdict], Any]] | None = None,
        batch_observers: Sequence[Callable[[list[Verdict]], Any]] = (),
        online: Callable[[], bool] = lambda: True,
        vacuity: Sequence[AntecedentWatch] = (),
        write_robustness: Callable[[dict[str, float], float], Any] | None = None,
        **kw: Any,
    ) -> None:
        self.online = online
        self.write_robustness = write_robustness
        # robustness_<property> -> the value last written: only changes are written again
        self.robustness: dict[str, float] = {}
        self._robust = {name for m in monitors if getattr(m, "robustness", False)
                        for name in m.properties}
        self.monitors = monitors
        self.vacuity = list(vacuity)
        self.effectors = effectors
        self.send_to_effector = send
        self.mode_of = mode_of
        # called with every verdict; the list is the caller's and is read at each record, so
        # observers may come and go during a run
        self.observers: list[Callable[[Verdict], Any]] = [] if observers is None else observers
        # called once per step (a record, the end, an external verdict) with the verdicts it
        # decided, in order: one call for a record's verdicts, not one per verdict
        self.batch_observers = list(batch_observers)
        # the latest verdict of each property
        self.latest: dict[str, Verdict] = {}
        self.outcomes: dict[str, PropertyOutcome] = {
            name: PropertyOutcome(name) for monitor in monitors for name in monitor.properties
        }
        self.records = 0
        self.monitor_failures = 0  # records on which a monitor raised
        # monitor -> records it failed on since it last worked
        self._failing: dict[PropertyMonitor, int] = {}
        self._dropped_watches: list[AntecedentWatch] = []  # watches that raised
        self._stale: dict[str, str] = {}  # property -> why it cannot be judged now
        super().__init__(**kw)

    def set_stale(self, signals: dict[str, str], time: float) -> None:
        """``signals`` (name -> why) are stale from ``time`` on, the others live: every property
        reading a stale one is in error at once, and on every record until it is live again."""
        stale = {}
        for monitor in self.monitors:
            reads = getattr(monitor, "reads", None)
            if reads is None:
                continue
            for name in monitor.properties:
                why = next((signals[s] for s in reads(name) if s in signals), None)
                if why is not None:
                    stale[name] = f"not judged on a stale reading: {why}"
        fresh = [name for name in stale if name not in self._stale]
        self._stale = stale
        if fresh:
            self._take([Verdict(name, self.records, time, False, stale[name]) for name in fresh])

    def observe(self, time: float, record: dict[str, Any]) -> list[Verdict]:
        """Feed one loop record to every monitor; returns the verdicts it decided."""
        index = self.records
        self.records += 1
        decided: list[Verdict] = []
        for monitor in self.monitors:
            try:
                verdicts = monitor.step(time, record)
            except Exception as exc:
                verdicts = self._failed(monitor, index, time, exc)
            else:
                if monitor in self._failing:
                    self._recovered(monitor, time)
            decided += verdicts
        if self._stale:
            decided = [self._unless_stale(verdict) for verdict in decided]
        self._take(decided)
        if self.write_robustness is not None and decided:
            self._write_robustness(decided, time)
        for watch in self.vacuity:
            try:
                watch.step(time, record)
            except Exception as exc:  # an antecedent it misses stays vacuous: said, not hidden
                self._watch_failed(watch, time, exc)
        return decided

    def _watch_failed(self, watch: AntecedentWatch, time: float, exc: Exception) -> None:
        self.vacuity.remove(watch)
        self._dropped_watches.append(watch)
        _log.error("watching the antecedents of %s failed at t=%s: %s: %s; those that have not "
                   "held so far are reported vacuous", _origin(watch), format_seconds(time),
                   type(exc).__name__, exc, exc_info=exc)

    def _unless_stale(self, verdict: Verdict) -> Verdict:
        why = self._stale.get(verdict.property)
        if why is None or verdict.value is None:
            return verdict
        # an error's robustness is -inf, as the monitors give it (fail closed)
        return verdict._replace(value=False, error=why, robustness=-math.inf,
                                robustness_interval=(-math.inf, -math.inf))

    def _write_robustness(self, verdicts: list[Verdict], time: float) -> None:
        """Hand on each property's robustness at the newest record this step judged, where it
        changed: one call for the step."""
        newest: dict[str, Verdict] = {}
        for verdict in verdicts:
            known = newest.get(verdict.property)
            if known is None or verdict.index >= known.index:
                newest[verdict.property] = verdict
        changed = {}
        for name, verdict in newest.items():
            if name not in self._robust:
                continue  # its monitor gives no robustness (an external verdict source)
            value = written_robustness(verdict)
            key = robustness_key(name)
            if self.robustness.get(key) != value:
                changed[key] = value
        if changed:
            self.robustness.update(changed)
            self.write_robustness(changed, time)

    def finish(self) -> list[Verdict]:
        """The end of the run: settle every monitor (``None``: the run ended before a verdict
        could be decided) and name the signals each property never judged waits for."""
        decided: list[Verdict] = []
        for monitor in self.monitors:
            try:
                verdicts = monitor.finish()
            except Exception as exc:
                verdicts = self._failed(monitor, self.records, self.clock.time, exc)
            decided += verdicts
        self._take(decided)
        for watch in list(self.vacuity):
            try:
                watch.finish()
            except Exception as exc:
                self._watch_failed(watch, self.clock.time, exc)
        watches = [*self.vacuity, *self._dropped_watches]
        for name, outcome in self.outcomes.items():
            if not outcome.judged:
                outcome.missing = self.missing(name)
            outcome.vacuous = tuple(u for watch in watches for u in watch.vacuous(name))
        return decided

    def add_monitor(self, monitor: PropertyMonitor) -> None:
        """Check ``monitor``'s properties too, from the next record on."""
        self.monitors.append(monitor)
        if getattr(monitor, "robustness", False):
            self._robust.update(monitor.properties)

    def take(self, verdict: Verdict) -> None:
        """A verdict decided outside the monitors (an external verdict source): counted, and
        the property's latest from now on."""
        self._take([verdict])

    def latest_verdict(self, name: str) -> Verdict | None:
        """The latest verdict of property ``name``, or None before its first."""
        return self.latest.get(name)

    def missing(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` waits for (none once it has started)."""
        for monitor in self.monitors:
            if name in monitor.properties:
                return tuple(monitor.missing(name))
        return ()

    def _take(self, verdicts: list[Verdict]) -> None:
        """Count the verdicts one step decided, note each property's latest, and hand them to
        the observers."""
        # a step may decide several verdicts of a bounded-future property, in no particular
        # order: the latest is the worst of those the newest deciding step gave
        newest: dict[str, Verdict] = {}
        for verdict in verdicts:
            name = verdict.property
            outcome = self.outcomes.get(name)
            if outcome is None:  # a monitor of another kind may decide about a name it did not list
                outcome = self.outcomes[name] = PropertyOutcome(name)
            outcome.add(verdict.value, verdict.error)
            known = newest.get(name)
            if known is None or _rank(verdict) > _rank(known):
                newest[name] = verdict
        self.latest.update(newest)
        for observer in self.observers:
            for verdict in verdicts:
                observer(verdict)
        if verdicts:
            for batch_observer in self.batch_observers:
                batch_observer(verdicts)

    def _failed(
        self, monitor: PropertyMonitor, index: int, time: float, exc: Exception
    ) -> list[Verdict]:
        """Every property of ``monitor`` in error for this record; the first failure of a run
        of them is logged with its traceback, the rest counted."""
        self.monitor_failures += 1
        why = f"the monitor raised {type(exc).__name__}: {exc}"
        failed = self._failing.get(monitor, 0)
        self._failing[monitor] = failed + 1
        if not failed:
            _log.error(
                "monitor of %s failed at t=%s: %s; its properties (%s) are in error until it "
                "works again",
                _origin(monitor), format_seconds(time), why, ", ".join(monitor.properties),
                exc_info=exc,
            )
        return [Verdict(name, index, time, False, why) for name in monitor.properties]

    def _recovered(self, monitor: PropertyMonitor, time: float) -> None:
        failed = self._failing.pop(monitor)
        _log.warning(
            "monitor of %s works again at t=%s, after failing on %d record(s)",
            _origin(monitor), format_seconds(time), failed,
        )

    def register_action(self, action: Action) -> ActionOutcome:
        """Send ``action`` to its effector if it may go: whether it was sent, and why."""
        return self.request("register_requested", action, "registration did not complete")

    def on_enter_checking_action(self) -> None:
        action = self.action
        assert action is not None
        effector = self.effectors.get(action.effector)
        if effector is None:
            self._refuse(f"unknown effector {action.effector!r}")
            return
        if not self.online():
            self._refuse("the managed system is offline")
            return
        if effector.modes is not None:
            mode = self.mode_of()
            # a modes chart has several active states (a state and its ancestors, parallel
            # regions); the simple mode signal has one value
            active = {mode} if isinstance(mode, str) or mode is None else set(mode)
            if not active.intersection(effector.modes):
                now = ", ".join(sorted(repr(m) for m in active if m is not None))
                where = f"mode {now}" if now else "an unknown mode (nothing vouches for it)"
                self._refuse(
                    f"not applicable in managed-system {where} ({effector.name} applies "
                    f"in {', '.join(effector.modes)})"
                )
                return
        try:
            note = self.send_to_effector(effector, action)
        except Exception as exc:
            self._refuse(f"effector unreachable: {exc}")
            return
        # what the sender says happened (a replay records the action instead of sending it)
        sent = f"sent to {effector.name} on {effector.topic}"
        self.answer(ActionOutcome(True, note if isinstance(note, str) else sent),
                    "action_registered")

    def _refuse(self, why: str) -> None:
        self.answer(ActionOutcome(False, why), "action_refused")


def written_robustness(verdict: Verdict) -> float:
    """The robustness the checker writes for ``verdict``: its final value; -inf for an error;
    for a verdict decided before its robustness is final (a bounded-future property), the
    lower bound of the interval known to contain it, so a reader never sees more margin than
    there is (-inf where the monitor gives no interval: nothing more is known)."""
    if verdict.error is not None:
        return -math.inf
    if verdict.robustness is not None:
        return verdict.robustness
    if verdict.robustness_interval is not None:
        return verdict.robustness_interval[0]
    return -math.inf


def _rank(verdict: Verdict) -> int:
    """How bad a verdict is for the checker's trust: error, false, inconclusive, true."""
    if verdict.error is not None:
        return 3
    return {False: 2, None: 1, True: 0}[verdict.value]


def _origin(monitor: PropertyMonitor) -> str:
    """The property file a monitor checks, for a log line."""
    spec = getattr(monitor, "spec", None)
    return getattr(spec, "source", None) or type(monitor).__name__
