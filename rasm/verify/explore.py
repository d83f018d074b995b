"""Exhaustive exploration of charts as they execute: every stable state, breadth first.

A *system* is what is explored: one chart under an environment (:class:`ChartExplorer`), or the
charts of an application bound together (:mod:`rasm.verify.app`). From the initial state, and
from every stable state found, each move of the environment is tried — queue one event (with each
of its data), or advance the clock — and the charts execute until they are stable again, exactly
as ``rasm simulate`` executes a line of an events file. Each macro step is a record the
properties judge.

A state is what decides the future (:meth:`System.key`): for each chart its configuration,
history memory, the context variables that are state, each timer's age up to its largest
threshold and the delayed events still queued (:mod:`rasm.verify.component`), and each
property's memory. One concrete snapshot per distinct state is kept until the state is expanded;
the exploration's memory grows with the number of states, not of paths. Breadth first, so the
first path found to a problem is a shortest one.
"""

from __future__ import annotations

import math
from array import array
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from sismic.model import Statechart

from rasm.statechart.simulate import MAX_STEPS
from rasm.times import format_nanoseconds
from rasm.verify.component import ChartRun, SettableClock, Step, freeze
from rasm.verify.environment import Environment
from rasm.verify.past import PastProperty, Record
from rasm.verify.regions import split_data

__all__ = ["ChartExplorer", "Exploration", "Move", "Problem", "System", "explore", "record_of"]


@dataclass(frozen=True)
class Move:
    """One step of the environment: an event (with its data) at ``time_ns``, or the clock
    moving to ``time_ns`` (``event`` None)."""

    time_ns: int
    event: str | None = None
    data: tuple[tuple[str, Any], ...] = ()

    def as_line(self) -> dict[str, Any]:
        """The move as a line of ``rasm simulate``'s events format."""
        text = format_nanoseconds(self.time_ns)
        time: int | float = int(text) if text.lstrip("-").isdigit() else float(text)
        if self.event is None:
            return {"time": time}
        line: dict[str, Any] = {"time": time, "event": self.event}
        if self.data:
            line["data"] = dict(self.data)
        return line


@dataclass
class Problem:
    """Something wrong found on some path: ``kind`` is one of raising code, non-determinism,
    contract, no stable state, property (``name`` the property's), stuck, or one of an
    application's checks."""

    kind: str
    message: str
    path: list[Move] | None = None
    name: str | None = None


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


class System(Protocol):
    """What :func:`explore` explores."""

    properties: list[PastProperty]
    clock: SettableClock
    skipped: int  # moves not even made: events nobody waits for

    def start(self) -> tuple[list[Record], list[tuple[str, str]], bool]:
        """The initial steps: records, failures (kind, message), whether it became stable."""

    def key(self) -> tuple:
        """The state of the charts (properties aside)."""

    def save(self) -> Any: ...

    def restore(self, snapshot: Any) -> None: ...

    def moves(self, *, skip_ignored: bool) -> list[Move]:
        """The environment's moves from the current stable state."""

    def ignored_record(self, move: Move) -> Record | None:
        """The record of ``move`` if it is an event nobody waits for (nothing then changes:
        it is not executed), else None."""

    def apply(self, move: Move) -> tuple[list[Record], list[tuple[str, str]], bool]:
        """Play ``move``: like :meth:`start`."""

    def configuration(self) -> frozenset[str]: ...

    def final(self) -> bool: ...

    def entered(self) -> set[str]: ...

    def checks(self, records: list[Record], move: Move | None) -> list[tuple[str, str]]:
        """Problems the system itself finds in a move's records (an application's checks)."""


class ChartExplorer:
    """One chart under an environment, as a :class:`System`."""

    def __init__(
        self,
        statechart: Statechart,
        environment: Environment,
        properties: list[PastProperty] = (),  # type: ignore[assignment]
        *,
        initial_context: Mapping[str, Any] | None = None,
        slice_context: bool = True,
        max_steps: int = MAX_STEPS,
    ) -> None:
        self.statechart = statechart
        self.properties = list(properties)
        watched = sorted(set().union(*(p.variables for p in self.properties))) if properties else []
        self.clock = SettableClock()
        self.run = ChartRun(
            statechart, self.clock, initial_context=initial_context, watch=set(watched),
            slice_context=slice_context, watched_values=watched, max_steps=max_steps,
        )
        self.code = self.run.code
        self.reads_time = any(_reads_time(p) for p in self.properties)
        self._regions: dict[tuple, list[tuple[tuple[str, Any], ...]]] = {}
        self.skipped = 0
        self._moves_now: int | None = None  # the time of the moves kept in _fixed_moves
        self._fixed_moves: dict[str, list[Move]] = {}  # the moves of events with fixed data
        self.environment = environment

    @property
    def environment(self) -> Environment:
        return self._environment

    @environment.setter
    def environment(self, environment: Environment) -> None:
        self._environment = environment
        # per event: its name, how many moves it stands for, per combination of the data the
        # environment fixes the keys left to split by the guards (and when there are none the
        # data of its moves, which then depends on no state), and whether there are none at all
        self._offers: list[tuple[str, int, list[tuple], bool]] = []
        for event in environment.events:
            wanted = self.code.guard_data.get(event.name, set())
            read = self.code.data.get(event.name, set())
            combos = []
            for fixed in event.combinations():
                free = wanted - set(fixed)
                datas = None if free else self._split(event.name, free, read, fixed, {})
                combos.append((fixed, free, read, datas))
            static = all(datas is not None for *_, datas in combos)
            self._offers.append((event.name, len(combos), combos, static))
        self._moves_now = None

    @property
    def interp(self) -> Any:
        return self.run.interp

    def start(self) -> tuple[list[Record], list[tuple[str, str]], bool]:
        return self._records(*self.run.execute())

    def key(self) -> tuple:
        key = self.run.key()
        return (key, self.clock.now_ns) if self.reads_time else key

    def save(self) -> Any:
        return (self.clock.now_ns, self.run.save())

    def restore(self, snapshot: Any) -> None:
        now, run = snapshot
        self.clock.set(now)
        self.run.restore(run)

    def configuration(self) -> frozenset[str]:
        return frozenset(self.run.configuration)

    def final(self) -> bool:
        return self.run.interp.final

    def entered(self) -> set[str]:
        return self.run.entered

    def checks(self, records: list[Record], move: Move | None) -> list[tuple[str, str]]:
        return []

    def moves(self, *, skip_ignored: bool) -> list[Move]:
        now = self.clock.now_ns
        if now != self._moves_now:
            self._moves_now = now
            self._fixed_moves = {}
        fixed_moves = self._fixed_moves
        out: list[Move] = []
        for name, count, combos, static in self._offers:
            if skip_ignored and self.run.ignores(name):
                self.skipped += count
                continue
            found = fixed_moves.get(name)
            if found is None:
                found = []
                for fixed, free, read, datas in combos:
                    if datas is None:  # split by the guards in the current state
                        datas = self._split(name, free, read, fixed, self.run.context)
                    found.extend(Move(now, name, data) for data in datas)
                if static:
                    fixed_moves[name] = found
            out.extend(found)
        if self.environment.clock_ns:
            out.extend(Move(now + amount) for amount in self.environment.clock_ns)
        else:
            due = self.run.next_deadline()
            if due is not None and due > now:
                out.append(Move(due))
        return out

    def _split(
        self, event: str, free: set[str], read: set[str], fixed: dict[str, Any],
        context: Mapping[str, Any],
    ) -> list[tuple[tuple[str, Any], ...]]:
        """The data of ``event`` to try: ``fixed`` given, ``free`` split into regions (cached by
        the values of the state variables, which are all the guards' comparisons can read)."""
        names = self.run.state_names if not self.run.all_state else sorted(context)
        cache = (event, tuple(sorted(fixed.items())), tuple(
            freeze(context.get(n)) for n in names
        ) if free else ())
        found = self._regions.get(cache)
        if found is None:
            datas, _ = split_data(self.code.guards.get(event, []), free, context, fixed)
            found = []
            for data in datas:
                for key in sorted(read - set(data)):
                    data[key] = None  # read by an action only: present, with no value
                found.append(tuple(sorted(data.items())))
            self._regions[cache] = found
        return found

    def ignored_record(self, move: Move) -> Record | None:
        if move.event is None or not self.run.ignores(move.event):
            return None
        context = self.run.context
        return Record(
            time_ns=self.clock.now_ns,
            configuration=frozenset(self.run.configuration),
            received=move.event,
            sent=frozenset(),
            context={n: context[n] for n in self.run._watched if n in context},
            transitions=False,
        )

    def apply(self, move: Move) -> tuple[list[Record], list[tuple[str, str]], bool]:
        if move.time_ns != self.clock.now_ns:
            self.clock.set(move.time_ns)
        if move.event is not None:
            self.run.queue(move.event, move.data)
        return self._records(*self.run.execute())

    def _records(
        self, steps: list[Step], failures: list[tuple[str, str]], stable: bool
    ) -> tuple[list[Record], list[tuple[str, str]], bool]:
        now = self.clock.now_ns
        return [record_of(step, now) for step in steps], failures, stable


def record_of(step: Step, now: int) -> Record:
    """A chart's step as the properties see it."""
    return Record(
        now, step.configuration, step.event,
        frozenset([name for name, _ in step.sent]) if step.sent else _NOTHING_SENT,
        step.context, step.transitions,
    )


_NOTHING_SENT: frozenset[str] = frozenset()


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


def explore(
    system: System, *, max_states: int = 100_000, goal: Callable[[], bool] | None = None,
    goal_problem: tuple[str, str] | None = None,
) -> Exploration:
    """Breadth-first search over ``system``'s states; see the module docstring.

    With ``goal`` (a test of the current state), every state found must be able to reach one
    where it holds: those that cannot are reported as ``goal_problem`` (kind, message), with a
    shortest path to the first of them."""
    props = system.properties
    # the largest window bound a property compares the time since its last record with
    horizon = max((b for p in props for b in _bounds(p)), default=0)
    result = Exploration(complete=False, states=0, transitions=0)
    # of each state found, the state it was found from (-1: none) and the move that led to it:
    # what a path is rebuilt from (arrays of machine integers: the exploration keeps one entry
    # per state, and one per transition when it checks a goal)
    parents = array("q")
    found_by: list[Move | None] = []
    index: dict[tuple, int] = {}
    seen_problem: set[tuple[str, str]] = set()

    def path_to(i: int | None, last: Move | None) -> list[Move]:
        moves = [] if last is None else [last]
        while i is not None and i >= 0 and found_by[i] is not None:
            moves.append(found_by[i])
            i = parents[i]
        moves.reverse()
        return moves

    def full_key(chart: tuple, prop_states: tuple, last_ns: int | None) -> tuple:
        if not props:
            return chart
        since = None if last_ns is None else min(system.clock.now_ns - last_ns, horizon)
        return (chart, prop_states, since)

    def judge(states: tuple, last_ns: int | None, records: list[Record],
              parent: int | None, move: Move | None) -> tuple[tuple, int | None]:
        if not props:
            return states, last_ns
        for record in records:
            dt = None if last_ns is None else record.time_ns - last_ns
            new = []
            for prop, state in zip(props, states, strict=True):
                value, state = prop.step(state, record, dt)
                new.append(state)
                if not value and prop.name not in result.violated:
                    result.violated[prop.name] = Problem(
                        "property", f"property {prop.name} violated at "
                        f"t={format_nanoseconds(record.time_ns)}",
                        path_to(parent, move), name=prop.name,
                    )
            states = tuple(new)
            last_ns = record.time_ns
        return states, last_ns

    def note(failures: list[tuple[str, str]], stable: bool, parent: int | None,
             move: Move | None) -> None:
        if not stable:
            failures = [*failures, (
                "no stable state",
                "the charts do not become stable: more than 10000 macro steps without an event "
                "(an eventless transition cycle?)",
            )]
        for kind, message in failures:
            if (kind, message) not in seen_problem:
                seen_problem.add((kind, message))
                result.problems.append(Problem(kind, message, path_to(parent, move)))

    def finished(complete: bool) -> Exploration:
        result.states = len(found_by)
        result.entered = set(system.entered())
        result.transitions += system.skipped
        result.complete = complete
        return result

    records, failures, stable = system.start()
    note([*failures, *system.checks(records, None)], stable, None, None)
    if not stable:  # the initial step never settles: there is nothing to explore from
        parents.append(-1)
        found_by.append(None)
        return finished(True)
    prop_states, last_ns = judge(tuple(p.initial() for p in props), None, records, None, None)
    result.configurations.update(record.configuration for record in records)
    chart = system.key()
    index[full_key(chart, prop_states, last_ns)] = 0
    parents.append(-1)
    found_by.append(None)
    frontier: deque[tuple[int, Any, tuple, tuple, int | None]] = deque(
        [(0, system.save(), chart, prop_states, last_ns)]
    )
    stuck_seen: set[frozenset[str]] = set()

    edges = (array("q"), array("q"))  # (from, to) of each transition, only to check the goal
    reached: list[bool] = [goal()] if goal is not None else []

    def add(key: tuple, parent: int, move: Move, entry: tuple) -> bool:
        """Queue a state not seen before; False when --max-states is reached."""
        if key in index:
            if goal is not None:
                edges[0].append(parent)
                edges[1].append(index[key])
            return True
        if len(found_by) >= max_states:
            return False
        found = index[key] = len(found_by)
        parents.append(parent)
        found_by.append(move)
        frontier.append((found, *entry))
        if goal is not None:
            edges[0].append(parent)
            edges[1].append(found)
            reached.append(goal())
        return True

    configurations = result.configurations
    while frontier:
        current, snap, own_chart, prop_states, last_ns = frontier.popleft()
        system.restore(snap)
        configuration = system.configuration()
        final = system.final()
        # without properties, events nobody waits for are not even made moves (their step
        # changes nothing); with them, their records are decided before any move changes the
        # charts: such an event is only consumed, so it is not executed
        moves = system.moves(skip_ignored=not props)
        ignored = [system.ignored_record(move) for move in moves] if props else None
        way_out = False
        dirty = False
        for i, move in enumerate(moves):
            result.transitions += 1
            if ignored is not None and ignored[i] is not None:
                new_props, new_last = judge(prop_states, last_ns, [ignored[i]], current, move)
                key = full_key(own_chart, new_props, new_last)
                if not add(key, current, move, (snap, own_chart, new_props, new_last)):
                    return finished(False)
                continue
            if dirty:
                system.restore(snap)
            dirty = True
            records, failures, stable = system.apply(move)
            found = system.checks(records, move)
            if failures or found or not stable:
                note([*failures, *found], stable, current, move)
            if not stable:  # reported: a state that never settles is no state to go on from
                way_out = True
                continue
            moved = False
            for record in records:
                configurations.add(record.configuration)
                moved = moved or record.transitions
            chart = system.key()
            if moved or chart != own_chart:
                way_out = True
            if props:
                new_props, new_last = judge(prop_states, last_ns, records, current, move)
                key = full_key(chart, new_props, new_last)
            else:  # the state is the charts'
                new_props, new_last, key = prop_states, last_ns, chart
            if key in index:
                if goal is not None:
                    edges[0].append(current)
                    edges[1].append(index[key])
            elif not add(key, current, move, (system.save(), chart, new_props, new_last)):
                return finished(False)
        if not way_out and not final and configuration not in stuck_seen:
            stuck_seen.add(configuration)
            result.problems.append(Problem(
                "stuck",
                "stuck in " + ", ".join(sorted(configuration)) + ": every event is ignored and "
                "no timer is pending",
                path_to(current, None),
            ))
    if goal is not None and goal_problem is not None:
        stranded = _cannot_reach(len(found_by), edges, reached)
        if stranded:
            kind, message = goal_problem
            result.problems.append(Problem(kind, message, path_to(min(stranded), None)))
    return finished(True)


def _cannot_reach(count: int, edges: tuple[array, array], goal: list[bool]) -> set[int]:
    """The states from which no path leads to one where the goal holds."""
    back: dict[int, list[int]] = {}
    for a, b in zip(*edges, strict=True):
        back.setdefault(b, []).append(a)
    can = {i for i in range(count) if goal[i]}
    stack = list(can)
    while stack:
        for a in back.get(stack.pop(), ()):
            if a not in can:
                can.add(a)
                stack.append(a)
    return set(range(count)) - can
