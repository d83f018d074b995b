"""One chart as the exploration runs it: its interpreter, snapshots of it, and its state key.

:class:`ChartRun` wraps the interpreter ``rasm run`` uses (:class:`rasm.statechart.Interpreter`)
on a clock the exploration sets, forward and back. It saves and restores everything a step can
change, executes until the chart is stable exactly as ``rasm simulate`` does, and gives the key
of the chart's state (:meth:`ChartRun.key`): the configuration, the history memory, the context
variables that are state (:mod:`rasm.verify.code`), each active timer's age up to its largest
threshold, and the delayed events still queued.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from typing import Any, NamedTuple

from sismic.clock import Clock
from sismic.exceptions import (
    ConflictingTransitionsError,
    ContractError,
    NonDeterminismError,
    PropertyStatechartError,
)
from sismic.model import Event, MacroStep, Statechart

from rasm.errors import ExecutionError
from rasm.statechart.interpreter import Interpreter, _copy_value, _names_used
from rasm.statechart.simulate import MAX_STEPS
from rasm.times import from_nanoseconds, nanoseconds
from rasm.verify.code import ChartCode, analyse_chart

__all__ = ["ChartRun", "SettableClock", "Step", "freeze"]

_IMMUTABLE = (bool, int, float, str, bytes, type(None))


class SettableClock(Clock):
    """A simulated clock the exploration may set back (to a saved state's time)."""

    def __init__(self) -> None:
        self._time = 0.0
        self.now_ns = 0

    @property
    def time(self) -> float:
        return self._time

    def set(self, ns: int) -> None:
        self.now_ns = ns
        self._time = from_nanoseconds(ns)


class Step(NamedTuple):
    """One macro step a chart took: what the properties and the reports need of it (a named
    tuple: the exploration makes one per macro step)."""

    configuration: frozenset[str]
    event: str | None
    sent: tuple[tuple[str, dict[str, Any]], ...]
    transitions: bool
    context: Mapping[str, Any]


def freeze(value: Any) -> Any:
    """A hashable stand-in for a context value (equal values, equal stand-ins)."""
    if isinstance(value, _IMMUTABLE):
        return value
    if isinstance(value, list | tuple):
        return (type(value).__name__, tuple(freeze(v) for v in value))
    if isinstance(value, dict):
        return ("dict", tuple(sorted(((repr(k), freeze(v)) for k, v in value.items()))))
    if isinstance(value, set | frozenset):
        return ("set", tuple(sorted(repr(freeze(v)) for v in value)))
    try:
        hash(value)
        return value
    except TypeError:
        return ("repr", repr(value))


def problem_kind(exc: BaseException) -> str:
    """The built-in problem a failed step is: non-determinism, contract or raising code."""
    cause = exc.__cause__ if isinstance(exc, ExecutionError) and exc.__cause__ else exc
    if isinstance(cause, NonDeterminismError | ConflictingTransitionsError):
        return "non-determinism"
    if isinstance(cause, ContractError):
        return "contract"
    if isinstance(cause, PropertyStatechartError):
        return "monitor"
    return "raising code"


def _context_snapshot(context: Mapping[str, Any]) -> tuple[Any, bool]:
    """The context's items when all its values are immutable (restoring them needs no copy of
    each value, and the snapshot is hashable); else a copy of it. With whether they are."""
    if all(type(v) in _IMMUTABLE for v in context.values()):
        return tuple(context.items()), True
    return {k: _copy_value(v) for k, v in context.items()}, False


class ChartRun:
    """One chart's interpreter under the exploration; see the module docstring.

    ``inputs`` are context variables its driver sets before each event (a stage chart's
    ``knowledge``, ``time``, ``iteration``…): not state, whatever reads them. ``watch`` are
    variables that are state whatever the chart does with them (those a property reads).
    """

    def __init__(
        self,
        statechart: Statechart,
        clock: SettableClock,
        *,
        initial_context: Mapping[str, Any] | None = None,
        watch: set[str] = frozenset(),  # type: ignore[assignment]
        inputs: set[str] = frozenset(),  # type: ignore[assignment]
        slice_context: bool = True,
        watched_values: list[str] = (),  # type: ignore[assignment]
        max_steps: int = MAX_STEPS,
    ) -> None:
        self.statechart = statechart
        self.clock = clock
        self.max_steps = max_steps  # macro steps one move may take before it "never settles"
        self.code: ChartCode = analyse_chart(statechart, watch)
        state = self.code.state_variables
        self.all_state = state is None or not slice_context
        self.state_names = sorted((state or set()) - set(inputs))
        self.inputs = set(inputs)
        self.reads_time = self.code.reads_time
        self.interp = Interpreter(
            statechart, clock=clock, initial_context=dict(initial_context or {})
        )
        self.entered: set[str] = set()  # every state some step entered
        self._watched = list(watched_values)
        self._timer_args: dict[str, Any] = {}
        self._timed = [
            (source, sorted({t.kind for t in timers}))
            for source, timers in sorted(self.code.timers.items())
        ]
        # event -> the states with a transition on it: an event none of them is active for is
        # only consumed
        self.handled: dict[str, set[str]] = {}
        for transition in statechart.transitions:
            if transition.event is not None:
                self.handled.setdefault(transition.event, set()).add(transition.source)
        self.contracts = any(
            getattr(x, kind, None)
            for x in [*statechart.transitions, *map(statechart.state_for, statechart.states)]
            for kind in ("preconditions", "postconditions", "invariants")
        )
        # states whose eventless transitions or timers may fire without an event
        self._unsettled = {t.source for t in statechart.transitions if t.event is None}
        self._unsettled |= set(self.code.timers)

    @property
    def context(self) -> dict[str, Any]:
        return self.interp._evaluator._context

    @property
    def configuration(self) -> set[str]:
        return self.interp._configuration

    # -- snapshots -------------------------------------------------------------------------
    def save(self) -> tuple:
        """Everything a step can change. A snapshot is never changed (:meth:`restore` copies
        out of it), and it is made of immutable parts where the values allow: equal ones can
        then be kept once (:class:`~rasm.verify.app.AppSystem` does)."""
        it = self.interp
        memory = it._memory
        return (
            it._initialized, it._time,
            tuple([(k, tuple(v) if v is not None else None) for k, v in memory.items()])
            if memory else (),
            frozenset(it._configuration), tuple(it._entry_time.items()),
            tuple(it._idle_time.items()), _context_snapshot(it._evaluator._context),
            tuple(it._internal_queue), tuple(it._external_queue),
            tuple(getattr(it._evaluator, "deadlines", None) or ()),
        )

    def restore(self, snap: tuple) -> None:
        it = self.interp
        (it._initialized, it._time, memory, configuration, entry, idle, context,
         internal, external, deadlines) = snap
        # (most charts have no history memory)
        it._memory = {k: (list(v) if v is not None else None) for k, v in memory} if memory else {}
        it._configuration = set(configuration)
        it._entry_time = dict(entry)
        it._idle_time = dict(idle)
        ctx = it._evaluator._context
        ctx.clear()
        values, immutable = context
        ctx.update(values if immutable else {k: _copy_value(v) for k, v in values.items()})
        it._internal_queue = list(internal)
        it._external_queue = list(external)
        if getattr(it._evaluator, "deadlines", None) is not None:
            it._evaluator.deadlines[:] = deadlines

    # -- the state key ---------------------------------------------------------------------
    def key(self) -> tuple:
        """What decides the chart's future: see the module docstring."""
        it = self.interp
        now = self.clock.now_ns
        context = it._evaluator._context
        if self.all_state:
            names = sorted(n for n in context if n not in self.inputs)
        else:
            names = self.state_names
        values = tuple([(n, freeze(context[n])) for n in names if n in context])
        configuration = it._configuration
        timers = []
        for source, kinds in self._timed:
            if source not in configuration:
                continue
            cap = self._timer_cap(source)
            for kind in kinds:
                since = it._entry_time.get(source) if kind == "after" else it._idle_time.get(source)
                start = nanoseconds(since)
                age = None if start is None else now - start
                if age is not None and cap is not None:
                    age = min(age, cap)
                timers.append((source, kind, age))
        # (most stable states have no queued event and no history memory)
        queued = tuple([
            (
                (nanoseconds(t) or 0) - now, e.name, type(e).__name__,
                freeze(dict(getattr(e, "data", {}) or {})),
            )
            for queue in (it._internal_queue, it._external_queue) for t, e in queue
        ]) if it._internal_queue or it._external_queue else ()
        memory = tuple(sorted(
            (k, tuple(v) if v is not None else None) for k, v in it._memory.items()
        )) if it._memory else ()
        return (
            frozenset(configuration), memory, values, tuple(timers), queued,
            now if self.reads_time else None,
        )

    def _timer_cap(self, source: str) -> int | None:
        """The largest threshold the timers of ``source`` compare its age with, in the current
        context (None when one cannot be evaluated: the age is then kept exactly)."""
        context = self.interp._evaluator._context
        best = 0
        for timer in self.code.timers[source]:
            compiled = self._timer_args.get(timer.seconds)
            if compiled is None:
                code = compile(ast.parse(timer.seconds, mode="eval"), "<timer>", "eval")
                compiled = self._timer_args[timer.seconds] = (code, sorted(_names_used(code)), {})
            code, names, known = compiled
            # a threshold is a function of the values of the names it reads: evaluated once
            # for each of them
            values = tuple(freeze(context.get(n, _ABSENT)) for n in names)
            ns = known.get(values, _ABSENT)
            if ns is _ABSENT:
                try:
                    ns = nanoseconds(eval(code, {}, dict(context)))  # noqa: S307 - chart code
                except Exception:
                    ns = None
                known[values] = ns
            if ns is None:
                return None
            best = max(best, ns)
        return best

    def ignores(self, event: str) -> bool:
        """Whether ``event`` is one no transition of the active states waits for: the step only
        consumes it, and nothing changes (a chart with contracts always executes it: an
        invariant may read ``received()``)."""
        if self.contracts:
            return False
        sources = self.handled.get(event)
        return not sources or sources.isdisjoint(self.interp._configuration)

    def next_deadline(self) -> int | None:
        """When a timer or delayed event of the stable chart falls due, in ns (None: never)."""
        due = Interpreter.next_deadline(self.interp)
        if due is None:
            return None
        return nanoseconds(due)

    # -- execution -------------------------------------------------------------------------
    def queue(
        self, name: str, data: Mapping[str, Any] | tuple[tuple[str, Any], ...] = ()
    ) -> None:
        """Queue event ``name`` with ``data`` (a mapping, or its items)."""
        event = Event(name, **dict(data)) if data else Event(name)
        # what Interpreter.queue(event) does, with the delay read from the data: getattr(event,
        # "delay") on an event without one formats an error message first
        self.interp._enqueue(event, event.data.get("delay", 0))

    def execute(self) -> tuple[list[Step], list[tuple[str, str]], bool]:
        """Execute until stable, as ``rasm simulate`` does: the steps taken, the failures
        (kind, message) and whether the chart became stable."""
        steps: list[Step] = []
        failures: list[tuple[str, str]] = []
        interp = self.interp
        context = interp._evaluator._context
        watched = self._watched
        entered = self.entered
        for _ in range(self.max_steps):
            try:
                macro: MacroStep | None = interp.execute_once()
            except Exception as exc:
                failures.append((problem_kind(exc), str(exc)))
                failure = interp.last_failure
                if failure is None or failure.event is None:
                    return steps, failures, True
                continue
            if macro is None:
                return steps, failures, True
            # what MacroStep's event, entered_states, sent_events and transitions say, in one
            # pass over its micro steps
            event = None
            sent: list[tuple[str, dict[str, Any]]] = []
            transitions = False
            for micro in macro.steps:
                if event is None and micro.event is not None:
                    event = micro.event.name
                if micro.entered_states:
                    entered.update(micro.entered_states)
                if micro.sent_events:
                    sent.extend((e.name, dict(e.data)) for e in micro.sent_events)
                if micro.transition is not None:
                    transitions = True
            steps.append(Step(
                configuration=frozenset(interp._configuration),
                event=event,
                sent=tuple(sent),
                transitions=transitions,
                context={n: context[n] for n in watched if n in context} if watched else _EMPTY,
            ))
            if self._settled(interp):
                return steps, failures, True
        return steps, failures, False

    def _settled(self, interp: Any) -> bool:
        """Whether the chart is surely stable after a step, without the step sismic would take
        to find out: no event queued, and no active state with an eventless transition or a
        timer (a chart with contracts always takes it: its invariants are checked there)."""
        if interp._internal_queue or interp._external_queue or self.contracts:
            return False
        if not self._unsettled.isdisjoint(interp._configuration):
            return False
        deadlines = getattr(interp._evaluator, "deadlines", None)
        if deadlines:
            deadlines.clear()  # those of guards before the step: none applies to this state
        return True


_EMPTY: dict[str, Any] = {}
_ABSENT = object()  # a name the context does not have
