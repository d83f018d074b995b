"""Tables computed once per statechart for :class:`~rasm.statechart.fast.FastInterpreter`.

Stock sismic answers every tree query (ancestors, descendants, depth, least common ancestor) by
walking the tree again, and scans every transition of the chart at each step. A chart does not
change while it runs, so :func:`tables_for` computes those answers once and shares them between
all the interpreters of the same chart. Everything here is derived from the chart alone: an
interpreter's run-time state (configuration, memory, queues, context) is never kept here.

The tables reproduce sismic's own algorithms (same orders, same tie-breaks), so that the fast
interpreter takes exactly the same decisions as the stock one.

What the tables depend on is the chart's structure: its states and their tree, its transitions
and their source, target, event and priority. Each time the interpreter is asked to step,
:meth:`ChartTables.check` finds out whether it was edited since (see :class:`ChartEditedError`).
Everything else (guards, actions, entry and exit code, initial states, history memory, contracts)
is read from the chart when it is used; a chart without any contract is spared contract
evaluation until a condition is added.

One kind of edit can escape a running interpreter: a transition changed in place (rotated, its
event or priority assigned) is caught only when a step selects it, so a change that would make it
selectable goes unseen (comparing every transition each time would cost more than a step); an
interpreter built after the edit sees it.
"""

from __future__ import annotations

import operator
import weakref
from collections import defaultdict
from itertools import combinations
from typing import Any

from sismic.exceptions import StatechartError as SismicStatechartError
from sismic.model import (
    CompoundState,
    DeepHistoryState,
    FinalState,
    OrthogonalState,
    ShallowHistoryState,
    Statechart,
    StateMixin,
    Transition,
)

from rasm.errors import StatechartError

__all__ = ["ChartEditedError", "ChartTables", "tables_for"]

# Kinds of states that stabilisation can act on (``Interpreter._create_stabilization_step``).
FINAL_CHILD_OF_ROOT = "final child of the root"
HISTORY = "history"
PARALLEL = "parallel"
COMPOUND = "compound"  # acted on when it has an initial state

# Verdicts of the pairwise check of ``Interpreter._sort_transitions``.
PAIR_OK = "ok"
PAIR_NON_DETERMINISM = "non-determinism"
PAIR_CONFLICT = "conflict"


class ChartEditedError(StatechartError, SismicStatechartError):
    """The statechart was edited after an interpreter that runs it was built.

    :class:`~rasm.statechart.fast.FastInterpreter` precomputes the chart's tree and transition
    tables when it is built, so it cannot follow an edit of the chart; it raises this error at the
    next step instead of running a chart that no longer exists. It is rasm's
    :class:`~rasm.errors.StatechartError` and, for code written for sismic, sismic's.
    """

    def __init__(self, statechart: Statechart, what: str) -> None:
        super().__init__(
            f"statechart {statechart.name!r} was edited after its interpreter was built ({what}): "
            "build a new interpreter for the edited chart (edit charts before running them), "
            "or run it with sismic.interpreter.Interpreter, which reads the chart at every step"
        )
        self.what = what


#: What the tables take from a transition (a subclass's own ``source`` and ``target`` derive from
#: these): an edit of the transition changes it.
_transition_key = operator.attrgetter("_source", "_target", "event", "priority")


class ChartTables:
    """Answers to the tree and transition queries of one statechart.

    Attributes are plain dicts keyed by state name (or by transition) so that the interpreter
    answers a query with one lookup.
    """

    def __init__(self, statechart: Statechart) -> None:
        # What check() compares the chart with: the chart's own containers, copied.
        self._states = dict(statechart._states)
        self._parent = dict(statechart._parent)
        self._transitions = list(statechart._transitions)
        # Transitions are keyed by identity here: the tables hold them, so no id is reused.
        self._keys = {id(t): _transition_key(t) for t in self._transitions}
        # A chart without any condition needs no contract evaluation, until one is added.
        self._contract_lists = [
            getattr(obj, kind, None)
            for obj in (*self._states.values(), *self._transitions)
            for kind in ("preconditions", "postconditions", "invariants")
        ]
        self.contracts = any(self._contract_lists)

        self.root = statechart.root
        names = statechart.states
        self.state: dict[str, StateMixin] = {n: statechart.state_for(n) for n in names}
        self.children = {n: tuple(statechart.children_for(n)) for n in names}
        self.ancestors = {n: tuple(statechart.ancestors_for(n)) for n in names}
        self.descendants = {n: tuple(statechart.descendants_for(n)) for n in names}
        self.descendant_set = {n: frozenset(d) for n, d in self.descendants.items()}
        self.depth = {n: len(a) + 1 for n, a in self.ancestors.items()}
        # Sort keys of stock sismic: the configuration by (depth, name), transitions and
        # stabilisation candidates by (-depth, name).
        self.config_key = {n: (d, n) for n, d in self.depth.items()}
        self.source_key = {n: (-d, n) for n, d in self.depth.items()}
        self._build_stabilization()
        self._build_history()
        self._build_selection()
        self._steps: dict[int, tuple[tuple[str, ...], tuple[str, ...]]] = {}
        self._pairs: dict[tuple[int, int], str] = {}
        self._orders: dict[tuple[int, ...], tuple[Transition, ...] | None] = {}

    def check(self, statechart: Statechart) -> None:
        """Raise :class:`ChartEditedError` if ``statechart`` was edited since the tables were
        built: a state added, removed, renamed or moved, a transition added or removed. A
        condition added to a chart that had no contract turns contract evaluation on.

        Run at every step, so it only compares the chart's containers with their copies (a few
        pointer comparisons). A transition whose source, target, event or priority is changed in
        place is caught when a step selects it (:meth:`check_transition`).
        """
        if statechart._transitions != self._transitions:
            raise ChartEditedError(statechart, "a transition was added or removed")
        if statechart._states != self._states or statechart._parent != self._parent:
            raise ChartEditedError(statechart, "a state was added, removed, renamed or moved")
        if not self.contracts and any(self._contract_lists):
            self.contracts = True  # conditions were added: evaluated from this step on

    def check_transition(self, statechart: Statechart, transition: Transition) -> None:
        """Raise :class:`ChartEditedError` if ``transition`` changed since the tables were built
        (``Statechart.rotate_transition``, or its event or priority assigned)."""
        if _transition_key(transition) != self._keys.get(id(transition)):
            raise ChartEditedError(statechart, f"{transition!r} was changed")

    def matches(self, statechart: Statechart) -> bool:
        """Whether the tables describe ``statechart`` as it is now (every transition compared)."""
        try:
            self.check(statechart)
            for transition in self._transitions:
                self.check_transition(statechart, transition)
        except ChartEditedError:
            return False
        return True

    # ---- states ---------------------------------------------------------------------------

    def _build_stabilization(self) -> None:
        """Which states stabilisation can act on when they are leaves, and how."""
        self.stabilization: dict[str, str] = {}
        for name, state in self.state.items():
            if isinstance(state, FinalState) and self.ancestors[name][:1] == (self.root,):
                self.stabilization[name] = FINAL_CHILD_OF_ROOT
            elif isinstance(state, (ShallowHistoryState, DeepHistoryState)):
                self.stabilization[name] = HISTORY
            elif isinstance(state, OrthogonalState) and self.children[name]:
                self.stabilization[name] = PARALLEL
            elif isinstance(state, CompoundState):
                self.stabilization[name] = COMPOUND
        self.parallel_children = {
            n: sorted(self.children[n]) for n, k in self.stabilization.items() if k == PARALLEL
        }
        self.names = frozenset(self.state)
        self.stabilizable = frozenset(self.stabilization)

    def _build_history(self) -> None:
        """For each compound state, its history children in document order (deep or not)."""
        self.history_children: dict[str, tuple[tuple[str, bool], ...]] = {}
        for name, state in self.state.items():
            if not isinstance(state, CompoundState):
                continue
            found = []
            for child in self.children[name]:
                child_state = self.state[child]
                if isinstance(child_state, DeepHistoryState):
                    found.append((child, True))
                elif isinstance(child_state, ShallowHistoryState):
                    found.append((child, False))
            if found:
                self.history_children[name] = tuple(found)

    # ---- transitions ----------------------------------------------------------------------

    def _build_selection(self) -> None:
        """Index transitions by event name (``None`` for eventless), in stock selection order.

        Stock ``_select_transitions`` groups the candidate transitions by source depth (deepest
        first), then by source name, then by priority (highest first), keeping document order
        inside a priority class. Each entry here is ``(source, ancestors, classes)`` in that order.
        """
        by_event: dict[str | None, dict[str, list[Transition]]] = defaultdict(dict)
        for t in self._transitions:
            by_event[t.event].setdefault(t.source, []).append(t)
        self.selection: dict[str | None, tuple[tuple[str, frozenset[str], tuple], ...]] = {}
        # False when priorities cannot be ordered: stock fails at run time, and so does this
        # interpreter, through stock's selection
        self.selection_ok = True
        for event, sources in by_event.items():
            entries = []
            for source in sorted(sources, key=self.source_key.__getitem__):
                groups: dict[Any, list[Transition]] = defaultdict(list)
                for t in sources[source]:
                    groups[t.priority].append(t)
                try:
                    order = sorted(groups, reverse=True)
                except TypeError:
                    self.selection_ok = False
                    order = list(groups)
                classes = tuple(tuple(groups[p]) for p in order)
                entries.append((source, frozenset(self.ancestors[source]), classes))
            self.selection[event] = tuple(entries)
        # Whether a step without a due event has nothing to select (no eventless transition).
        self.eventless = None in self.selection or not self.selection_ok

    def _last_before(self, source: str, lca: str | None) -> str:
        """The highest ancestor-or-self of ``source`` strictly below ``lca`` (stock's loop)."""
        last = source
        for state in self.ancestors[source]:
            if state == lca:
                break
            last = state
        return last

    def lca(self, first: str, second: str) -> str | None:
        """``Statechart.least_common_ancestor``: first ancestor of ``first`` above ``second``."""
        second_ancestors = self.ancestors[second]
        for state in self.ancestors[first]:
            if state in second_ancestors:
                return state
        return None

    def steps_for(self, transition: Transition) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(exit candidates, entered states) of an external transition, as ``_create_steps``.

        Exit candidates are the descendants of the highest exited state, deepest first, then that
        state; the interpreter keeps the active ones.
        """
        found = self._steps.get(id(transition))
        if found is None:
            source, target = transition.source, transition.target
            lca = self.lca(source, target)
            last = self._last_before(source, lca)
            exits = self.descendants[last][::-1] + (last,)
            entered = [target]
            for state in self.ancestors[target]:
                if state == lca:
                    break
                entered.insert(0, state)
            found = self._steps[id(transition)] = (exits, tuple(entered))
        return found

    def pair_verdict(self, t1: Transition, t2: Transition) -> str:
        """Stock ``_sort_transitions`` check of one pair of simultaneously enabled transitions."""
        key = (id(t1), id(t2))
        verdict = self._pairs.get(key)
        if verdict is None:
            verdict = self._pairs[key] = self._pair_verdict(t1, t2)
        return verdict

    def order(self, transitions: list[Transition]) -> tuple[Transition, ...] | None:
        """Stock order of simultaneously enabled transitions (by source, deepest first), kept
        per set of transitions; None when some pair of them is not ``PAIR_OK``."""
        key = tuple([id(t) for t in transitions])
        found = self._orders.get(key, False)
        if found is False:
            if all(self.pair_verdict(t1, t2) == PAIR_OK for t1, t2 in combinations(transitions, 2)):
                found = tuple(sorted(transitions, key=lambda t: self.source_key[t.source]))
            else:
                found = None
            self._orders[key] = found
        return found

    def _pair_verdict(self, t1: Transition, t2: Transition) -> str:
        lca = self.lca(t1.source, t2.source)
        # two enabled transitions of the root have no ancestor in common: a non-deterministic
        # choice like any other state's (stock sismic fails there with "State None does not
        # exist", looking for the root's parent)
        if lca is None or not isinstance(self.state[lca], OrthogonalState):
            return PAIR_NON_DETERMINISM
        for transition in (t1, t2):
            last = self._last_before(transition.source, lca)
            if transition.target and (
                transition.target != last and transition.target not in self.descendant_set[last]
            ):
                return PAIR_CONFLICT
        return PAIR_OK


# The tables of every chart an interpreter runs, for as long as the chart lives: the tables hold
# the chart's states and transitions, never the chart itself.
_CACHE: weakref.WeakKeyDictionary[Statechart, ChartTables] = weakref.WeakKeyDictionary()


def tables_for(statechart: Statechart) -> ChartTables:
    """The tables of ``statechart``, shared by all its interpreters; rebuilt if it was edited."""
    tables = _CACHE.get(statechart)
    if tables is None or not tables.matches(statechart):
        tables = _CACHE[statechart] = ChartTables(statechart)
    return tables
