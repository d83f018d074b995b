"""Tables precomputed once per statechart for :class:`~rasm.statechart.fast.FastInterpreter`.

Stock sismic answers every tree query (ancestors, descendants, depth, least common ancestor) by
walking the tree again, and scans every transition of the chart at each step. A loaded chart does
not change, so :func:`tables_for` computes those answers once and shares them between all the
interpreters of the same chart. Everything here is derived from the chart alone: an interpreter's
run-time state (configuration, memory, queues, context) is never cached here.

The tables reproduce sismic's own algorithms (same orders, same tie-breaks), so that the fast
interpreter takes exactly the same decisions as the stock one.
"""

from __future__ import annotations

import weakref
from collections import defaultdict
from typing import Any

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

__all__ = ["ChartTables", "tables_for"]

# Kinds of states that stabilisation can act on (``Interpreter._create_stabilization_step``).
FINAL_CHILD_OF_ROOT = 1
HISTORY = 2
PARALLEL = 3
INITIAL = 4

# Verdicts of the pairwise check of ``Interpreter._sort_transitions``.
PAIR_OK = 0
PAIR_NON_DETERMINISM = 1
PAIR_CONFLICT = 2
PAIR_NO_LCA = 3  # stock calls state_for(None), which raises StatechartError


def _contracts(obj: Any) -> tuple[int, int, int]:
    return (
        len(getattr(obj, "preconditions", ()) or ()),
        len(getattr(obj, "postconditions", ()) or ()),
        len(getattr(obj, "invariants", ()) or ()),
    )


def fingerprint(statechart: Statechart) -> tuple:
    """What the tables depend on; a change means the chart was edited after tables were built."""
    states = []
    for name in statechart.states:
        state = statechart.state_for(name)
        states.append(
            (
                name,
                id(state),
                statechart.parent_for(name),
                getattr(state, "initial", None),
                getattr(state, "memory", None),
                _contracts(state),
                state.name,
                bool(getattr(state, "on_entry", None)),
                bool(getattr(state, "on_exit", None)),
            )
        )
    transitions = tuple(
        (id(t), t.source, t.target, t.event, t.priority, _contracts(t))
        for t in statechart.transitions
    )
    return tuple(states), transitions


class ChartTables:
    """Answers to the tree and transition queries of one (unchanging) statechart.

    Attributes are plain dicts keyed by state name (or by ``id()`` of a transition) so that the
    interpreter reads them with one lookup.
    """

    # Read several times per micro step: slots, read without an instance dict lookup.
    __slots__ = (
        "ancestors", "children", "config_key", "depth", "descendant_set", "descendants",
        "entry_code", "event_driven", "events_from", "exit_code", "exit_enter", "fingerprint",
        "has_code", "has_contracts", "history_children", "invariant_states", "names_plain",
        "needs_inv", "needs_post", "needs_pre", "pairs", "parallel_children", "root",
        "selection", "selection_ok", "source_key", "stabilization", "state", "statechart",
        "transitions",
    )

    def __init__(self, statechart: Statechart) -> None:
        self.statechart = statechart
        self.fingerprint = fingerprint(statechart)
        self.root = statechart.root
        names = statechart.states
        self.state: dict[str, StateMixin] = {n: statechart.state_for(n) for n in names}
        self.children: dict[str, tuple[str, ...]] = {
            n: tuple(statechart.children_for(n)) for n in names
        }
        self.ancestors: dict[str, tuple[str, ...]] = {
            n: tuple(statechart.ancestors_for(n)) for n in names
        }
        self.descendants: dict[str, tuple[str, ...]] = {
            n: tuple(statechart.descendants_for(n)) for n in names
        }
        self.descendant_set = {n: frozenset(d) for n, d in self.descendants.items()}
        self.depth = {n: len(a) + 1 for n, a in self.ancestors.items()}
        # Sort keys of stock sismic: configuration by (depth, name), transitions and
        # stabilisation candidates by (-depth, name).
        self.config_key = {n: (d, n) for n, d in self.depth.items()}
        self.source_key = {n: (-d, n) for n, d in self.depth.items()}
        # States with entry or exit code (sismic's calls for the others do nothing), and whether
        # each state's `name` (a property) is the name it is registered under, so that the
        # interpreter can use the names it holds.
        states = self.state.items()
        self.entry_code = frozenset(n for n, s in states if getattr(s, "on_entry", None))
        self.exit_code = frozenset(n for n, s in states if getattr(s, "on_exit", None))
        self.names_plain = all(s.name == n for n, s in self.state.items())
        self._build_stabilization()
        self._build_history()
        self._build_contracts()
        self._build_selection()
        self.exit_enter: dict[int, tuple[tuple[str, ...], tuple[str, ...]]] = {}
        self.pairs: dict[tuple[int, int], int] = {}

    # Tables are derived from the chart alone: copies of an interpreter share them, and a pickled
    # interpreter rebuilds them from its (pickled) chart.
    def __copy__(self) -> ChartTables:
        return self

    def __deepcopy__(self, memo: dict) -> ChartTables:
        return self

    def __reduce__(self) -> tuple:
        return tables_for, (self.statechart,)

    # ---- states ---------------------------------------------------------------------------

    def _build_stabilization(self) -> None:
        """Which states stabilisation can act on when they are leaves, and how."""
        self.stabilization: dict[str, int] = {}
        for name, state in self.state.items():
            if isinstance(state, FinalState) and self.ancestors[name][:1] == (self.root,):
                self.stabilization[name] = FINAL_CHILD_OF_ROOT
            elif isinstance(state, (ShallowHistoryState, DeepHistoryState)):
                self.stabilization[name] = HISTORY
            elif isinstance(state, OrthogonalState) and self.children[name]:
                self.stabilization[name] = PARALLEL
            elif isinstance(state, CompoundState) and state.initial:
                self.stabilization[name] = INITIAL
        self.parallel_children = {
            n: sorted(self.children[n]) for n, k in self.stabilization.items() if k == PARALLEL
        }

    def _build_history(self) -> None:
        """For each compound state, its history children in document order (deep=True/False)."""
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

    def _build_contracts(self) -> None:
        """Which states and transitions need which contract evaluation.

        ``PythonEvaluator.evaluate_preconditions`` also freezes the context for ``__old__`` when
        the object has invariants or postconditions, so such objects need the call even without
        preconditions.
        """
        self.needs_pre: set[int] = set()
        self.needs_post: set[int] = set()
        self.needs_inv: set[int] = set()
        self.invariant_states: set[str] = set()
        objects: list[Any] = list(self.state.values()) + list(self.statechart.transitions)
        for obj in objects:
            pre, post, inv = _contracts(obj)
            if pre or post or inv:
                self.needs_pre.add(id(obj))
            if post:
                self.needs_post.add(id(obj))
            if inv:
                self.needs_inv.add(id(obj))
                if isinstance(obj, StateMixin):
                    self.invariant_states.add(obj.name)
        self.has_contracts = bool(self.needs_pre)
        # whether any state or transition has code a step runs (the preamble runs once)
        self.has_code = any(
            getattr(state, "on_entry", None) or getattr(state, "on_exit", None)
            for state in self.state.values()
        ) or any(t.action for t in self.statechart.transitions)

    # ---- transitions ----------------------------------------------------------------------

    def _build_selection(self) -> None:
        """Index transitions by event name (``None`` for eventless), in stock selection order.

        Stock ``_select_transitions`` groups the candidate transitions by source depth (deepest
        first), then by source name, then by priority (highest first), keeping document order
        inside a priority class. Each entry here is ``(source, ancestors, classes)`` in that order.
        """
        self.transitions: tuple[Transition, ...] = tuple(self.statechart.transitions)
        by_event: dict[str | None, dict[str, list[Transition]]] = defaultdict(dict)
        for t in self.transitions:
            by_event[t.event].setdefault(t.source, []).append(t)
        self.selection: dict[str | None, tuple[tuple[str, frozenset[str], tuple], ...]] = {}
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
                    # Unorderable priorities: stock fails at run time; let it (fallback path).
                    self.selection_ok = False
                    order = list(groups)
                classes = tuple(tuple(groups[p]) for p in order)
                entries.append((source, frozenset(self.ancestors[source]), classes))
            self.selection[event] = tuple(entries)
        # Whether a step without a due event can only move the time (no eventless transition)
        self.event_driven = self.selection_ok and None not in self.selection
        # Event names some transition of a given state listens to.
        self.events_from: dict[str, frozenset[str]] = {}
        for name in self.state:
            self.events_from[name] = frozenset(
                t.event for t in self.transitions if t.source == name and t.event is not None
            )

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
        key = id(transition)
        found = self.exit_enter.get(key)
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
            found = self.exit_enter[key] = (exits, tuple(entered))
        return found

    def pair_verdict(self, t1: Transition, t2: Transition) -> int:
        """Stock ``_sort_transitions`` check of one pair of simultaneously enabled transitions."""
        key = (id(t1), id(t2))
        verdict = self.pairs.get(key)
        if verdict is None:
            verdict = self.pairs[key] = self._pair_verdict(t1, t2)
        return verdict

    def _pair_verdict(self, t1: Transition, t2: Transition) -> int:
        lca = self.lca(t1.source, t2.source)
        if lca is None:
            return PAIR_NO_LCA
        if not isinstance(self.state[lca], OrthogonalState):
            return PAIR_NON_DETERMINISM
        for transition in (t1, t2):
            last = self._last_before(transition.source, lca)
            if transition.target and (
                transition.target != last and transition.target not in self.descendant_set[last]
            ):
                return PAIR_CONFLICT
        return PAIR_OK


_CACHE: weakref.WeakKeyDictionary[Statechart, ChartTables] = weakref.WeakKeyDictionary()


def tables_for(statechart: Statechart) -> ChartTables:
    """The tables of ``statechart``, shared by all its interpreters; rebuilt if it was edited."""
    tables = _CACHE.get(statechart)
    if tables is None or tables.fingerprint != fingerprint(statechart):
        tables = _CACHE[statechart] = ChartTables(statechart)
    return tables
