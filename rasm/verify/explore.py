"""Exhaustive exploration of a chart as it executes: every stable state, breadth first.

The chart runs on rasm's own interpreter (the one ``rasm run`` and ``rasm simulate`` use), macro
step by macro step. From the initial state, and from every stable state found, each move of the
environment is tried: queue one event (with each of its data), or advance the clock. The chart
executes until it is stable again, exactly as ``rasm simulate`` executes a line of an events
file. Each macro step is a record the properties judge.

A state is what decides the chart's future (:meth:`ChartExplorer.key`): the active
configuration, the history memory, the context variables that are state
(:mod:`rasm.verify.code`), the age of every timer up to the largest threshold it is compared
with, the delayed events still queued, and each property's memory. One concrete interpreter
snapshot per distinct state is kept until the state is expanded; the exploration's memory grows
with the number of states, not of paths. Breadth first, so the first path found to a problem is
a shortest one.
"""

from __future__ import annotations

import ast
import math
from collections import deque
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from sismic.clock import Clock
from sismic.exceptions import ConflictingTransitionsError, ContractError, NonDeterminismError
from sismic.model import Event, Statechart

from rasm.errors import ExecutionError
from rasm.statechart.interpreter import Interpreter
from rasm.statechart.simulate import MAX_STEPS
from rasm.times import from_nanoseconds, nanoseconds
from rasm.verify.code import ChartCode, analyse_chart
from rasm.verify.environment import Environment
from rasm.verify.past import PastProperty, Record
from rasm.verify.regions import split_data

__all__ = ["ChartExplorer", "Move", "Problem", "Exploration"]

_next_deadline = Interpreter.next_deadline


@dataclass(frozen=True)
class Move:
    """One step of the environment: an event (with its data) at ``time_ns``, or the clock
    moving to ``time_ns`` (``event`` None)."""

    time_ns: int
    event: str | None = None
    data: tuple[tuple[str, Any], ...] = ()

    def as_line(self) -> dict[str, Any]:
        """The move as a line of ``rasm simulate``'s events format."""
        from rasm.times import format_nanoseconds

        time = _json_time(format_nanoseconds(self.time_ns))
        if self.event is None:
            return {"time": time}
        line: dict[str, Any] = {"time": time, "event": self.event}
        if self.data:
            line["data"] = dict(self.data)
        return line


def _json_time(text: str) -> int | float:
    number = float(text)
    return int(number) if number.is_integer() and "." not in text and "e" not in text else number


@dataclass
class Problem:
    """Something wrong found on some path: ``kind`` is one of raising code, non-determinism,
    contract, no stable state, property (``name`` the property's), unreachable, stuck."""

    kind: str
    message: str
    path: list[Move] | None = None
    name: str | None = None


@dataclass
class _Node:
    """A distinct state found: how it was reached (for the counterexamples)."""

    parent: int | None
    move: Move | None
    depth: int


@dataclass
class Exploration:
    """What an exploration found."""

    complete: bool
    states: int
    transitions: int
    configurations: set[frozenset[str]] = field(default_factory=set)
    entered: set[str] = field(default_factory=set)  # every state some step entered
    problems: list[Problem] = field(default_factory=list)
    violated: dict[str, Problem] = field(default_factory=dict)
    capped_regions: bool = False


def _freeze(value: Any) -> Any:
    """A hashable stand-in for a context value (equal values, equal stand-ins)."""
    if isinstance(value, bool | int | float | str | bytes | type(None)):
        return value
    if isinstance(value, list | tuple):
        return (type(value).__name__, tuple(_freeze(v) for v in value))
    if isinstance(value, dict):
        return ("dict", tuple(sorted(((repr(k), _freeze(v)) for k, v in value.items()))))
    if isinstance(value, set | frozenset):
        return ("set", tuple(sorted(repr(_freeze(v)) for v in value)))
    try:
        hash(value)
        return value
    except TypeError:
        return ("repr", repr(value))


def _problem_kind(exc: BaseException) -> str:
    cause = exc.__cause__ if isinstance(exc, ExecutionError) and exc.__cause__ else exc
    if isinstance(cause, NonDeterminismError | ConflictingTransitionsError):
        return "non-determinism"
    if isinstance(cause, ContractError):
        return "contract"
    return "raising code"


class ChartExplorer:
    """The transition system of one chart under an environment, explored breadth first."""

    def __init__(
        self,
        statechart: Statechart,
        environment: Environment,
        properties: list[PastProperty] = (),  # type: ignore[assignment]
        *,
        initial_context: Mapping[str, Any] | None = None,
        slice_context: bool = True,
    ) -> None:
        self.statechart = statechart
        self.environment = environment
        self.properties = list(properties)
        roots = set().union(*(p.variables for p in self.properties)) if self.properties else set()
        self.code: ChartCode = analyse_chart(statechart, roots)
        state_vars = self.code.state_variables
        self.state_variables = None if (state_vars is None or not slice_context) else state_vars
        self.reads_time = self.code.reads_time or any(
            _reads_time(p) for p in self.properties
        )
        self.clock = _SettableClock()
        self.interp = Interpreter(
            statechart, clock=self.clock, initial_context=dict(initial_context or {})
        )
        self.now_ns = 0
        self._timer_args: dict[str, Any] = {}
        # the largest window bound a property compares the time since its last record with
        self._property_horizon = max(
            (b for p in self.properties for b in _bounds(p)), default=0
        )
        self.capped_regions = False
        self.entered: set[str] = set()  # every state some step entered
        self._property_variables = sorted(
            set().union(*(p.variables for p in self.properties)) if self.properties else ()
        )
        self._state_names = sorted(self.state_variables or ())
        self._timed_states = [
            (state, sorted({t.kind for t in timers}))
            for state, timers in sorted(self.code.timers.items())
        ]
        # event -> the states with a transition on it (an event none of them is active for is
        # only consumed)
        self._handled: dict[str, set[str]] = {}
        for transition in statechart.transitions:
            if transition.event is not None:
                self._handled.setdefault(transition.event, set()).add(transition.source)
        self._contracts = any(
            getattr(x, kind, None)
            for x in [*statechart.transitions, *map(statechart.state_for, statechart.states)]
            for kind in ("preconditions", "postconditions", "invariants")
        )
        self._regions: dict[tuple, list[dict[str, Any]]] = {}
        # states whose eventless transitions or timers may fire without an event
        self._unsettled = {t.source for t in statechart.transitions if t.event is None}
        self._unsettled |= set(self.code.timers)
        self.skipped = 0  # moves not even made: events the active states ignore

    # -- snapshots -------------------------------------------------------------------------
    def save(self) -> tuple:
        it = self.interp
        ev = it._evaluator
        return (
            self.now_ns, it._initialized, it._time,
            {k: (list(v) if v is not None else None) for k, v in it._memory.items()},
            set(it._configuration), dict(it._entry_time), dict(it._idle_time),
            _context_snapshot(it._evaluator._context),
            list(it._internal_queue), list(it._external_queue),
            list(getattr(ev, "deadlines", None) or ()),
        )

    def restore(self, snap: tuple) -> None:
        it = self.interp
        (self.now_ns, it._initialized, it._time, memory, configuration, entry, idle, context,
         internal, external, deadlines) = snap
        it._memory = {k: (list(v) if v is not None else None) for k, v in memory.items()}
        it._configuration = set(configuration)
        it._entry_time = dict(entry)
        it._idle_time = dict(idle)
        ctx = it._evaluator._context
        ctx.clear()
        values, immutable = context
        ctx.update(values if immutable else {k: _copy(v) for k, v in values.items()})
        it._internal_queue = list(internal)
        it._external_queue = list(external)
        ev = it._evaluator
        if getattr(ev, "deadlines", None) is not None:
            ev.deadlines[:] = deadlines
        self.clock.time = from_nanoseconds(self.now_ns)

    # -- the state key ---------------------------------------------------------------------
    def chart_key(self) -> tuple:
        """What decides the chart's future (see the module docstring), properties aside."""
        it = self.interp
        context = it._evaluator._context
        names = sorted(context) if self.state_variables is None else self._state_names
        values = tuple((n, _freeze(context[n])) for n in names if n in context)
        configuration = it._configuration
        timers = []
        for state, kinds in self._timed_states:
            if state not in configuration:
                continue
            cap = self._timer_cap(state)
            for kind in kinds:
                since = it._entry_time.get(state) if kind == "after" else it._idle_time.get(state)
                start = nanoseconds(since)
                age = None if start is None else self.now_ns - start
                if age is not None and cap is not None:
                    age = min(age, cap)
                timers.append((state, kind, age))
        queued = tuple(
            (
                (nanoseconds(t) or 0) - self.now_ns, e.name, type(e).__name__,
                _freeze(dict(getattr(e, "data", {}) or {})),
            )
            for queue in (it._internal_queue, it._external_queue) for t, e in queue
        )
        memory = tuple(sorted(
            (k, tuple(v) if v is not None else None) for k, v in it._memory.items()
        )) if it._memory else ()
        return (
            frozenset(configuration), memory, values, tuple(timers), queued,
            self.now_ns if self.reads_time else None,
        )

    def key(self, chart_key: tuple, prop_states: tuple, since_record: int | None) -> tuple:
        """The whole state: the chart's, each property's memory, and how long ago the last
        record was (as far as a property's windows can tell)."""
        if not self.properties:
            return chart_key
        since = None if since_record is None else min(since_record, self._property_horizon)
        return (chart_key, prop_states, since)

    def ignores(self, move: Move) -> bool:
        """Whether ``move`` is an event no transition of the active states waits for: the step
        only consumes it, and nothing changes (charts with contracts are always executed: an
        invariant may read ``received()``)."""
        if move.event is None or self._contracts:
            return False
        sources = self._handled.get(move.event)
        return not sources or sources.isdisjoint(self.interp._configuration)

    def ignored_record(self, move: Move) -> Record:
        """The record of the step that consumes an ignored event (see :meth:`ignores`)."""
        context = self.interp._evaluator._context
        wanted = self._property_variables
        return Record(
            time_ns=self.now_ns,
            configuration=frozenset(self.interp._configuration),
            received=move.event,
            sent=_NONE,
            context={n: context[n] for n in wanted if n in context} if wanted else _EMPTY,
            transitions=False,
        )

    def _timer_cap(self, state: str) -> int | None:
        """The largest threshold the timers of ``state`` compare its age with, in the current
        context (None when one cannot be evaluated: the age is then kept exactly)."""
        context = self.interp._evaluator._context
        best = 0
        for timer in self.code.timers[state]:
            compiled = self._timer_args.get(timer.seconds)
            if compiled is None:
                compiled = self._timer_args[timer.seconds] = compile(
                    ast.parse(timer.seconds, mode="eval"), "<timer>", "eval"
                )
            try:
                ns = nanoseconds(eval(compiled, {}, dict(context)))  # noqa: S307 - chart code
            except Exception:
                return None
            if ns is None:
                return None
            best = max(best, ns)
        return best

    # -- moves -----------------------------------------------------------------------------
    def moves(self, *, skip_ignored: bool = False) -> Iterator[Move]:
        """The environment's moves from the current (stable) state (with ``skip_ignored``,
        not the events :meth:`ignores` would say are only consumed)."""
        context = self.interp._evaluator._context
        configuration = self.interp._configuration
        for event in self.environment.events:
            if skip_ignored and not self._contracts:
                sources = self._handled.get(event.name)
                if not sources or sources.isdisjoint(configuration):
                    self.skipped += len(event.combinations())
                    continue
            wanted = self.code.guard_data.get(event.name, set())
            read = self.code.data.get(event.name, set())
            for fixed in event.combinations():
                free = wanted - set(fixed)
                for data in self._split(event.name, free, read, fixed, context):
                    yield Move(self.now_ns, event.name, data)
        if self.environment.clock_ns:
            for amount in self.environment.clock_ns:
                yield Move(self.now_ns + amount)
        else:
            due = _next_deadline(self.interp)
            if due is not None:
                due_ns = nanoseconds(due)
                if due_ns is not None and due_ns > self.now_ns:
                    yield Move(due_ns)

    def _split(
        self, event: str, free: set[str], read: set[str], fixed: dict[str, Any],
        context: Mapping[str, Any],
    ) -> list[tuple[tuple[str, Any], ...]]:
        """The data of ``event`` to try: ``fixed`` given, ``free`` split into regions (cached by
        the values of the state variables, which are all the guards' comparisons can read)."""
        names = self._state_names if self.state_variables is not None else sorted(context)
        cache = (event, tuple(sorted(fixed.items())), tuple(
            _freeze(context.get(n)) for n in names
        ) if free else ())
        found = self._regions.get(cache)
        if found is None:
            datas, capped = split_data(self.code.guards.get(event, []), free, context, fixed)
            self.capped_regions |= capped
            found = []
            for data in datas:
                for key in sorted(read - set(data)):
                    data[key] = None  # read by an action only: present, with no value
                found.append(tuple(sorted(data.items())))
            self._regions[cache] = found
        return found

    def apply(self, move: Move) -> tuple[list[Record], list[tuple[str, str]], bool]:
        """Play ``move`` from the current state: the macro steps taken, the failures
        (kind, message) and whether the chart became stable."""
        if move.time_ns != self.now_ns:
            self.now_ns = move.time_ns
            self.clock.time = from_nanoseconds(move.time_ns)
        if move.event is not None:
            self.interp.queue(Event(move.event, **dict(move.data)))
        return self.execute()

    def execute(self) -> tuple[list[Record], list[tuple[str, str]], bool]:
        """Execute until stable, as ``rasm simulate`` does: the records of the macro steps
        taken (each with the configuration and the variables the properties read as after
        it), the failures (kind, message), and whether the chart became stable."""
        records: list[Record] = []
        failures: list[tuple[str, str]] = []
        interp = self.interp
        context = interp._evaluator._context
        wanted = self._property_variables
        for _ in range(MAX_STEPS):
            try:
                macro = interp.execute_once()
            except Exception as exc:
                failures.append((_problem_kind(exc), str(exc)))
                failure = interp.last_failure
                if failure is None or failure.event is None:
                    return records, failures, True
                continue
            if macro is None:
                return records, failures, True
            self.entered.update(macro.entered_states)
            records.append(Record(
                time_ns=self.now_ns,
                configuration=frozenset(interp._configuration),
                received=macro.event.name if macro.event is not None else None,
                sent=frozenset(e.name for e in macro.sent_events) if macro.sent_events else _NONE,
                context={n: context[n] for n in wanted if n in context} if wanted else _EMPTY,
                transitions=bool(macro.transitions),
            ))
            if self._settled(interp):
                return records, failures, True
        return records, failures, False

    def _settled(self, interp: Any) -> bool:
        """Whether the chart is surely stable after a step, without the step sismic would take
        to find out: no event queued, and no active state with an eventless transition or a
        timer (a chart with contracts always takes it: its invariants are checked there)."""
        if interp._internal_queue or interp._external_queue or self._contracts:
            return False
        configuration = interp._configuration
        if not self._unsettled.isdisjoint(configuration):
            return False
        deadlines = getattr(interp._evaluator, "deadlines", None)
        if deadlines:
            deadlines.clear()  # those of guards before the step: none applies to this state
        return True


_NONE: frozenset[str] = frozenset()
_EMPTY: dict[str, Any] = {}


class _SettableClock(Clock):
    """A simulated clock the exploration may set back (to a saved state's time)."""

    def __init__(self) -> None:
        self._time = 0.0

    @property
    def time(self) -> float:
        return self._time

    @time.setter
    def time(self, value: float) -> None:
        self._time = value


_IMMUTABLE = (bool, int, float, str, bytes, type(None))


def _context_snapshot(context: Mapping[str, Any]) -> tuple[dict[str, Any], bool]:
    """A copy of the context, and whether all its values are immutable (then restoring it
    needs no copy of each value)."""
    if all(type(v) in _IMMUTABLE for v in context.values()):
        return dict(context), True
    return {k: _copy(v) for k, v in context.items()}, False


def _copy(value: Any) -> Any:
    from rasm.statechart.interpreter import _copy_value

    return _copy_value(value)


def _reads_time(prop: PastProperty) -> bool:
    from rasm.properties import ast as A

    stack = [prop.formula]
    while stack:
        node = stack.pop()
        if isinstance(node, A.Time):
            return True
        stack.extend(A.children(node))
    return False


def _bounds(prop: PastProperty) -> Iterator[int]:
    from rasm.properties import ast as A

    stack = [prop.formula]
    while stack:
        node = stack.pop()
        bound = getattr(node, "bound", None)
        if bound is not None:
            yield bound.high_ns if bound.high_ns != math.inf else bound.low_ns
        stack.extend(A.children(node))


def explore(explorer: ChartExplorer, *, max_states: int = 100_000) -> Exploration:
    """Breadth-first search over ``explorer``'s states; see the module docstring."""
    props = explorer.properties
    result = Exploration(complete=False, states=0, transitions=0)
    nodes: list[_Node] = []
    index: dict[tuple, int] = {}
    seen_problem: set[tuple[str, str]] = set()

    def path_to(i: int, last: Move | None) -> list[Move]:
        moves = [] if last is None else [last]
        while i is not None and nodes[i].move is not None:
            moves.append(nodes[i].move)
            i = nodes[i].parent
        moves.reverse()
        return moves

    def judge(states: tuple, last_ns: int | None, steps: list[Record],
              parent: int | None, move: Move | None) -> tuple[tuple, int | None]:
        for record in steps:
            dt = None if last_ns is None else record.time_ns - last_ns
            new = []
            for prop, state in zip(props, states, strict=True):
                value, state = prop.step(state, record, dt)
                new.append(state)
                if not value and prop.name not in result.violated:
                    result.violated[prop.name] = Problem(
                        "property", f"property {prop.name} violated at "
                        f"t={from_nanoseconds(record.time_ns):g}",
                        path_to(parent, move) if parent is not None else [],
                        name=prop.name,
                    )
            states = tuple(new)
            last_ns = record.time_ns
        return states, last_ns

    def note(failures: list[tuple[str, str]], stable: bool, parent: int | None,
             move: Move | None) -> None:
        for kind, message in failures:
            if (kind, message) not in seen_problem:
                seen_problem.add((kind, message))
                path = path_to(parent, move) if parent is not None else []
                result.problems.append(Problem(kind, message, path))
        if not stable:
            message = (
                f"the chart does not become stable: more than {MAX_STEPS} macro steps without "
                "an event (an eventless transition cycle?)"
            )
            if ("no stable state", message) not in seen_problem:
                seen_problem.add(("no stable state", message))
                path = path_to(parent, move) if parent is not None else []
                result.problems.append(Problem("no stable state", message, path))

    def since(last_ns: int | None) -> int | None:
        return None if last_ns is None else explorer.now_ns - last_ns

    steps, failures, stable = explorer.execute()
    note(failures, stable, None, None)
    prop_states, last_ns = judge(tuple(p.initial() for p in props), None, steps, None, None)
    result.configurations.update(record.configuration for record in steps)
    chart = explorer.chart_key()
    index[explorer.key(chart, prop_states, since(last_ns))] = 0
    nodes.append(_Node(None, None, 0))
    frontier: deque[tuple[int, tuple, tuple, tuple, int | None]] = deque(
        [(0, explorer.save(), chart, prop_states, last_ns)]
    )
    stuck_seen: set[frozenset[str]] = set()

    def add(key: tuple, parent: int, move: Move, entry: tuple) -> bool:
        """Queue a state not seen before; False when --max-states is reached."""
        if key in index:
            return True
        if len(nodes) >= max_states:
            return False
        index[key] = len(nodes)
        nodes.append(_Node(parent, move, nodes[parent].depth + 1))
        frontier.append((index[key], *entry))
        return True

    while frontier:
        current, snap, own_chart, prop_states, last_ns = frontier.popleft()
        explorer.restore(snap)
        configuration = frozenset(explorer.interp._configuration)
        final = explorer.interp.final
        moves = list(explorer.moves(skip_ignored=not props))
        # decided before any move changes the interpreter: events nobody waits for are only
        # consumed, so they are not executed
        ignored = [explorer.ignores(move) for move in moves]
        records = [explorer.ignored_record(m) if skip and props else None
                   for m, skip in zip(moves, ignored, strict=True)]
        way_out = False
        dirty = False
        for move, skip, record in zip(moves, ignored, records, strict=True):
            result.transitions += 1
            if skip:
                if not props:
                    continue  # the same state again
                new_props, new_last = judge(prop_states, last_ns, [record], current, move)
                key = explorer.key(own_chart, new_props, 0)
                if not add(key, current, move, (snap, own_chart, new_props, new_last)):
                    return _stopped(result, explorer, nodes)
                continue
            if dirty:
                explorer.restore(snap)
            dirty = True
            steps, failures, stable = explorer.apply(move)
            note(failures, stable, current, move)
            new_props, new_last = judge(prop_states, last_ns, steps, current, move)
            result.configurations.update(record.configuration for record in steps)
            chart = explorer.chart_key()
            if chart != own_chart or any(record.transitions for record in steps):
                way_out = True
            key = explorer.key(chart, new_props, since(new_last))
            if key not in index and not add(
                key, current, move, (explorer.save(), chart, new_props, new_last)
            ):
                return _stopped(result, explorer, nodes)
        if not way_out and not final and configuration not in stuck_seen:
            stuck_seen.add(configuration)
            result.problems.append(Problem(
                "stuck",
                "stuck in " + ", ".join(sorted(configuration)) + ": every event is ignored and "
                "no timer is pending",
                path_to(current, None) if current else [],
            ))
    result.states = len(nodes)
    result.entered = explorer.entered
    result.transitions += explorer.skipped
    result.complete = True
    return result


def _stopped(result: Exploration, explorer: ChartExplorer, nodes: list) -> Exploration:
    """The exploration reached --max-states: what it found so far, incomplete."""
    result.states = len(nodes)
    result.entered = explorer.entered
    result.transitions += explorer.skipped
    return result
