"""A faster sismic interpreter with the stock semantics, on exact time.

:class:`FastInterpreter` subclasses :class:`sismic.interpreter.Interpreter` and overrides its
private step machinery. It takes the same decisions in the same order (same macro and micro steps,
same guard, action and contract evaluations, same meta-events, same errors and messages) but for
one thing: time is exact (:mod:`rasm.statechart.timers`). The interpreter's time is the clock's
to the nanosecond, and timers and delayed events fall due at their deadline, where stock's binary
arithmetic can miss it (entered at 7.7, stock's ``after(2)`` is false at 9.7). Otherwise only the
bookkeeping is cheaper:

- tree queries (ancestors, descendants, depth, least common ancestor) come from tables computed
  once per chart (:mod:`rasm.statechart.fast.tables`), and so does the pairwise conflict check of
  simultaneous transitions;
- transitions are looked up in an index by event name, already in stock selection order, instead
  of scanning every transition of the chart at each step;
- contracts are evaluated only for the states and transitions that declare conditions, and not
  at all in a chart without any;
- the sorted configuration is kept until the configuration changes;
- meta-events are built only when someone listens, and a bound property statechart is executed
  only for the meta-events it could react to (:class:`~rasm.statechart.fast.PropertyListener`).

Attributes keep the names, types and meaning of stock sismic (``_configuration``, ``_memory``,
``_time``, queues, ...), so code that snapshots and restores them keeps working: the sorted
configuration is kept for one ``_configuration`` set, and a counter of the changes made to it.

The chart must not be edited while it runs: the tables describe it as it was when the interpreter
was built. Each call to :meth:`~FastInterpreter.execute` or
:meth:`~FastInterpreter.execute_once` checks that it was not
(:class:`~rasm.statechart.fast.ChartEditedError`).
"""

from __future__ import annotations

import bisect
import warnings
from collections.abc import Callable, Iterable
from itertools import combinations
from typing import Any

from sismic.clock import SynchronizedClock
from sismic.code import Evaluator, PythonEvaluator
from sismic.exceptions import ConflictingTransitionsError, NonDeterminismError
from sismic.interpreter import Interpreter
from sismic.model import (
    Event,
    InternalEvent,
    MacroStep,
    MetaEvent,
    MicroStep,
    Statechart,
    StateMixin,
    Transition,
)

from rasm.statechart.fast import tables as ft
from rasm.statechart.fast.listener import PropertyListener
from rasm.statechart.fast.meta_guards import NO_EVENT
from rasm.statechart.timers import ExactTimerEvaluator, deadline
from rasm.times import FAST, to_the_nanosecond

__all__ = ["FastInterpreter"]


def _name_of(event: Event) -> str | None:
    """The name of an event carried by a meta-event: the discriminant of guards reading
    ``event.event.name`` (:mod:`rasm.statechart.fast.meta_guards`); None when it is no string."""
    name = getattr(event, "name", None)
    return name if isinstance(name, str) else None


def _declares_any(obj: Any) -> bool:
    """Whether a state or transition declares a contract.

    sismic's evaluators find nothing to check on an object without conditions of the kind asked
    for; ``PythonEvaluator.evaluate_preconditions`` also saves the context for ``__old__`` when
    the object has postconditions or invariants, so it is called for any contract.
    """
    return bool(
        getattr(obj, "preconditions", None)
        or getattr(obj, "postconditions", None)
        or getattr(obj, "invariants", None)
    )


def _queue_order(item: tuple[float, Event]) -> tuple[float, bool]:
    """Where a queued (time, event) goes: by time, internal events before external ones."""
    return item[0], not isinstance(item[1], InternalEvent)


def _scan(
    entries: tuple,
    event: Event | None,
    states: set[str],
    evaluate_guard: Callable[..., Any],
) -> list[Transition]:
    """Stock selection over one group of the index (deepest source first, priority classes
    highest first): the transitions whose guard holds, in order."""
    selected: list[Transition] = []
    ignored: set[str] = set()  # sources (and their ancestors) that already fired
    for source, ancestors, classes in entries:
        if source not in states or source in ignored:
            continue
        for transitions in classes:
            found = False
            for transition in transitions:
                if transition.guard is None or evaluate_guard(transition, event):
                    selected.append(transition)
                    found = True
            if found:
                ignored.update(ancestors)
                ignored.add(source)
                break
    return selected


class FastInterpreter(Interpreter):
    """Drop-in replacement for :class:`sismic.interpreter.Interpreter`, several times faster.

    Same constructor, public API and semantics, on exact time: the default evaluator is
    :class:`~rasm.statechart.timers.ExactTimerEvaluator` (stock's ``PythonEvaluator`` may be
    passed, and then compares its timers as stock does). The statechart must not be edited
    while an interpreter runs it: a step raises :class:`~rasm.statechart.fast.ChartEditedError`
    then.
    """

    def __init__(
        self,
        statechart: Statechart,
        *,
        evaluator_klass: Callable[..., Evaluator] = ExactTimerEvaluator,
        initial_context: Any = None,
        clock: Any = None,
        ignore_contract: bool = False,
    ) -> None:
        # Set before the stock constructor: it runs the preamble, which may call active().
        self._tables = ft.tables_for(statechart)
        self._conf_version = 0  # bumped at each change of _configuration made by a step
        self._sorted_conf: tuple[set[str], int, int, list[str]] | None = None
        self._in_execute = False  # within execute(), whose steps are checked for edits at once
        super().__init__(
            statechart,
            evaluator_klass=evaluator_klass,
            initial_context=initial_context,
            clock=clock,
            ignore_contract=ignore_contract,
        )
        self._time = to_the_nanosecond(self._time)

    # Copies and pickles leave the tables out: they are the chart's, found again from it.
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_tables"]
        state["_sorted_conf"] = None
        state["_in_execute"] = False
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._tables = ft.tables_for(self._statechart)

    def __repr__(self) -> str:
        # Stock's text for this class itself, so that messages embedding the repr of a property
        # interpreter (PropertyStatechartError) read exactly as with stock sismic.
        name = "Interpreter" if type(self) is FastInterpreter else type(self).__name__
        return f"{name}({self._statechart!r})"

    # ---- public API -----------------------------------------------------------------------

    @property
    def configuration(self) -> list[str]:
        """Active state names ordered by depth, ties broken by name (as stock sismic)."""
        return list(self._sorted_configuration())

    def _sorted_configuration(self) -> list[str]:
        """The configuration as :attr:`configuration` orders it, computed once per change."""
        conf = self._configuration
        cached = self._sorted_conf
        # The set itself is compared, not only its changes: the platform's atomic layer
        # restores a failed step by putting a copy in its place.
        if cached is None or cached[:3] != (conf, self._conf_version, len(conf)):
            try:
                order = sorted(conf, key=self._tables.config_key.__getitem__)
            except KeyError:  # an unknown name: stock raises its StatechartError
                return super().configuration
            cached = self._sorted_conf = (conf, self._conf_version, len(conf), order)
        return cached[3]

    def bind_property_statechart(
        self,
        statechart: Statechart,
        *,
        interpreter_klass: Callable | None = None,
    ) -> Callable[[MetaEvent], Any]:
        """Bind a property statechart, executed by a :class:`FastInterpreter` by default.

        Same behaviour as stock sismic; the returned listener is a
        :class:`~rasm.statechart.fast.PropertyListener`, which skips the meta-events the property
        statechart cannot react to.
        """
        if isinstance(statechart, Interpreter):  # sismic's deprecated form: stock's listener
            return super().bind_property_statechart(statechart)
        klass = FastInterpreter if interpreter_klass is None else interpreter_klass
        interpreter = klass(statechart, clock=SynchronizedClock(self))
        skips = isinstance(interpreter, FastInterpreter) and isinstance(
            interpreter._evaluator, PythonEvaluator
        )
        listener = PropertyListener(interpreter, skips=skips)
        self.attach(listener)
        return listener

    def listening(self, name: str | None) -> list[Transition]:
        """The transitions of active states that listen to event ``name`` (None: eventless)."""
        conf = self._configuration
        return [
            transition
            for source, _, classes in self._tables.selection.get(name, ())
            if source in conf
            for transitions in classes
            for transition in transitions
        ]

    # ---- macro step -----------------------------------------------------------------------

    def execute(self, max_steps: int = -1) -> list[MacroStep]:
        """Stock ``execute``. The chart is checked for edits once, before its first step: nothing
        outside the interpreter runs between its steps."""
        self._tables.check(self._statechart)
        self._in_execute = True
        try:
            return super().execute(max_steps)
        finally:
            self._in_execute = False

    def execute_once(self) -> MacroStep | None:
        """Stock ``execute_once``, with meta-events raised only to listeners and invariants
        checked only where there are some."""
        if not self._in_execute:
            self._tables.check(self._statechart)
        # to the nanosecond: a clock moved in steps of 0.1 reads 0.30000000000000004, and every
        # time compared with this one (entry times, queued events) is then the float of "0.3"
        now = self.clock.time
        if now.__class__ is float and -FAST < now < FAST:  # to_the_nanosecond's usual case
            self._time = round(now * 1e9) / 1e9
        else:
            self._time = to_the_nanosecond(now)
        self._sent_events.clear()
        # (each meta-event is raised only if someone listens: building it is most of the cost)
        if self._listeners:
            self._notify("step started", None, time=self._time)

        computed_steps = self._compute_steps()
        if computed_steps:
            if computed_steps[0].event is not None:
                event = self._select_event(consume=True)
                if self._listeners:
                    self._notify("event consumed", _name_of(event), event=event)
            else:
                event = None

            if hasattr(self._evaluator, "on_step_starts"):
                warnings.warn(  # noqa: B028 (stock's warning, same stack level)
                    "Evaluator.on_step_starts is deprecated since 1.4.0.",
                    DeprecationWarning,
                )
                self._evaluator.on_step_starts(event)

            executed_steps = []
            for step in computed_steps:
                executed_steps.append(self._apply_step(step))
                executed_steps.extend(self._stabilize())
            macro_step: MacroStep | None = MacroStep(self._time, executed_steps)
        else:
            macro_step = None

        if self._tables.contracts and not self._ignore_contract:
            for name in self._sorted_configuration():
                state = self._tables.state[name]
                if getattr(state, "invariants", None):
                    self._evaluate_contract_conditions(state, "invariants", macro_step)

        if self._listeners:
            self._notify("step ended", None)
        return macro_step

    def _state(self, name: str) -> StateMixin:
        """``statechart.state_for(name)``, from the tables (stock raises for an unknown name)."""
        state = self._tables.state.get(name)
        return self._statechart.state_for(name) if state is None else state

    # ---- events ---------------------------------------------------------------------------

    def queue(
        self, event_or_name: str | Event, *event_or_names: str | Event, **parameters: Any
    ) -> FastInterpreter:
        """Stock ``queue``."""
        for event in (event_or_name, *event_or_names):
            if isinstance(event, str):
                # its delay is the one given here (reading it back from the event goes through
                # Event.__getattr__, which formats an error message when there is none)
                self._enqueue(Event(event, **parameters), parameters.get("delay", 0))
            else:
                self._queue_event(event)
        return self

    def _queue_event(self, event: Event) -> None:
        self._enqueue(event, getattr(event, "delay", 0))

    def _enqueue(self, event: Event, delay: Any) -> None:
        """Stock queueing (by time, internal events first), with bisect's own key function; the
        event is due at the exact deadline (:func:`~rasm.statechart.timers.deadline`)."""
        internal = isinstance(event, InternalEvent)
        queue: list = self._internal_queue if internal else self._external_queue
        time = self._time if delay.__class__ is int and not delay else deadline(self._time, delay)
        position = bisect.bisect_right(queue, (time, not internal), key=_queue_order)
        queue.insert(position, (time, event))

    def _raise_event(self, event: InternalEvent | MetaEvent) -> None:
        """Stock ``_raise_event``; the meta-events about a sent event go through _notify."""
        if isinstance(event, InternalEvent):
            self._queue_event(event)
            name = _name_of(event)
            self._notify("event sent", name, event=event)
            if hasattr(event, "delay"):
                self._notify("delayed event sent", name, event=event)
        else:
            super()._raise_event(event)

    def _notify(self, name: str, value: Any, **data: Any) -> None:
        """Raise the meta-event ``name`` (with ``data``) to every listener, as stock does.

        ``value`` is the meta-event's discriminant, what guards of property statecharts read
        (:mod:`rasm.statechart.fast.meta_guards`): a :class:`PropertyListener` whose property
        could not react to the meta-event only moves the property's time, as delivering it
        would. The meta-event is built only for a listener that receives it.
        """
        meta = None
        for listener in self._listeners:
            if isinstance(listener, PropertyListener) and not listener.wants(name, value):
                listener.skip()
                continue
            if meta is None:
                meta = MetaEvent(name, **data)
            listener(meta)

    def _select_event(self, *, consume: bool = False) -> Event | None:
        """Stock ``_select_event``: the first due event, internal ones first."""
        for queue in (self._internal_queue, self._external_queue):
            if queue and queue[0][0] <= self._time:
                return queue.pop(0)[1] if consume else queue[0][1]
        return None

    # ---- transition selection -------------------------------------------------------------

    def _compute_steps(self) -> list[MicroStep]:
        """Stock ``_compute_steps``, looking for transitions only where some could be selected."""
        if not self._initialized:
            self._initialized = True
            return [MicroStep(entered_states=[self._statechart.root])]  # type: ignore[list-item]
        event = self._select_event()
        if event is None and not self._tables.eventless:
            return []  # no event and no eventless transition: nothing to select
        transitions = self._select_transitions(event, self._configuration)
        if not transitions:
            # no event, no step; or an empty step, so that the event is consumed
            return [] if event is None else [MicroStep(event=event)]
        transitions = self._sort_transitions(transitions)
        event = None if transitions[0].event is None else event
        return self._create_steps(event, transitions)

    def _select_transitions(
        self,
        event: Event | None,
        states: set[str],
        *,
        eventless_first: bool = True,
        inner_first: bool = True,
    ) -> list[Transition]:
        """Stock selection (eventless first, inner-first, priorities) from the event index."""
        tables = self._tables
        if not (eventless_first and inner_first and tables.selection_ok):
            return super()._select_transitions(
                event, states, eventless_first=eventless_first, inner_first=inner_first
            )
        evaluate_guard = self._evaluator.evaluate_guard
        selected: list[Transition] = []
        if None in tables.selection:
            selected = _scan(tables.selection[None], None, states, evaluate_guard)
        name = getattr(event, "name", None)
        if not selected and name is not None and name in tables.selection:
            selected = _scan(tables.selection[name], event, states, evaluate_guard)
        # the index files transitions by what they were: one changed in place is caught here,
        # before it is taken for what it was
        for transition in selected:
            tables.check_transition(self._statechart, transition)
        return selected

    def _sort_transitions(self, transitions: list[Transition]) -> list[Transition]:
        """Stock order and conflict checks, with the pairwise verdicts kept per chart."""
        if len(transitions) > 1:
            tables = self._tables
            ordered = tables.order(transitions)  # (the same transitions are enabled together often)
            if ordered is not None:
                return list(ordered)
            for t1, t2 in combinations(transitions, 2):
                verdict = tables.pair_verdict(t1, t2)
                if verdict == ft.PAIR_OK:
                    continue
                if verdict == ft.PAIR_NON_DETERMINISM:
                    klass, what = NonDeterminismError, "Non-determinist choice between transitions"
                else:
                    klass, what = ConflictingTransitionsError, "Conflicting transitions:"
                raise klass(
                    f"{what} {t1} and {t2}"
                    f"\nConfiguration is {self.configuration}\nEvent is {t1.event}"
                    f"\nTransitions are:{transitions}\n",
                )
            key = tables.source_key
            transitions = sorted(transitions, key=lambda t: key[t.source])
        return transitions

    def _create_steps(
        self,
        event: Event | None,
        transitions: Iterable[Transition],
    ) -> list[MicroStep]:
        """One micro step per transition, from the precomputed exit and entry lists."""
        steps = []
        for transition in transitions:
            if transition.target is None:
                steps.append(MicroStep(event=event, transition=transition))
                continue
            exits, entered = self._tables.steps_for(transition)
            exited = [s for s in exits if s in self._configuration]
            steps.append(MicroStep(event, transition, list(entered), exited))
        return steps

    # ---- stabilisation --------------------------------------------------------------------

    def _create_stabilization_step(self, names: Iterable[str]) -> MicroStep | None:
        """Stock stabilisation: act on the deepest (then first by name) actionable leaf."""
        tables = self._tables
        active = names if isinstance(names, (set, frozenset)) else set(names)
        if not tables.names.issuperset(active):
            return super()._create_stabilization_step(names)  # stock raises
        best = None
        # (only the states stabilisation can act on: set operations, most states are not)
        for name in tables.stabilizable.intersection(active):
            if tables.stabilization[name] == ft.COMPOUND and not tables.state[name].initial:
                continue
            if not active.isdisjoint(tables.descendant_set[name]):
                continue  # not a leaf
            if best is None or tables.source_key[name] < tables.source_key[best]:
                best = name
        if best is None:
            return None
        kind = tables.stabilization[best]
        state = tables.state[best]
        if kind == ft.FINAL_CHILD_OF_ROOT:
            return MicroStep(exited_states=[best, tables.root])  # type: ignore[list-item]
        if kind == ft.HISTORY:
            states_to_enter = self._memory.get(best, [state.memory])  # type: ignore[attr-defined]
            states_to_enter.sort(  # type: ignore[union-attr]
                key=lambda x: (self._statechart.depth_for(x), x)
            )
            return MicroStep(entered_states=states_to_enter, exited_states=[best])
        if kind == ft.PARALLEL:
            return MicroStep(entered_states=list(tables.parallel_children[best]))
        return MicroStep(entered_states=[state.initial])  # type: ignore[attr-defined]

    # ---- micro step -----------------------------------------------------------------------

    def _apply_step(self, step: MicroStep) -> MicroStep:
        """Stock ``_apply_step``: same calls, same order, same meta-events."""
        tables = self._tables
        states = tables.state
        chart = self._statechart  # state_for() raises stock's error for an unknown name
        entered_states = [states.get(n) or chart.state_for(n) for n in step.entered_states]
        exited_states = [states.get(n) or chart.state_for(n) for n in step.exited_states]
        # what was active before the step, for history memory (only charts with history)
        active_configuration = set(self._configuration) if tables.history_children else set()
        # contracts are checked where sismic's evaluator would find something to check
        contracts = tables.contracts and not self._ignore_contract
        sent_events: list[Event] = []

        for state in exited_states:
            name = state.name
            sent_events.extend(self._evaluator.execute_on_exit(state))
            for child, deep in tables.history_children.get(name, ()):
                # Stock's asserts, spelt out: pytest rewrites the asserts of plugin packages
                # (rasm is one), which would change the exception's message.
                if deep:
                    active = active_configuration.intersection(tables.descendants[name])
                    if __debug__ and not len(active) >= 1:
                        raise AssertionError
                else:
                    active = active_configuration.intersection(tables.children[name])
                    if __debug__ and not len(active) == 1:
                        raise AssertionError
                self._memory[child] = list(active)
            self._configuration.remove(name)
            self._conf_version += 1
            if contracts and getattr(state, "postconditions", None):
                self._evaluate_contract_conditions(state, "postconditions", step)
            if self._listeners:
                self._notify("state exited", name, state=name)

        transition = step.transition
        if transition:
            contracted = contracts and _declares_any(transition)
            if contracted:
                self._evaluate_contract_conditions(transition, "preconditions", step)
                self._evaluate_contract_conditions(transition, "invariants", step)
            sent_events.extend(self._evaluator.execute_action(transition, step.event))
            if contracted:
                self._evaluate_contract_conditions(transition, "postconditions", step)
                self._evaluate_contract_conditions(transition, "invariants", step)
            self._idle_time[transition.source] = self._time
            if self._listeners:
                self._notify(
                    "transition processed",
                    NO_EVENT if step.event is None else _name_of(step.event),
                    source=transition.source,
                    target=transition.target,
                    event=step.event,
                )

        for state in entered_states:
            if contracts and _declares_any(state):
                self._evaluate_contract_conditions(state, "preconditions", step)
            sent_events.extend(self._evaluator.execute_on_entry(state))
            name = state.name
            self._configuration.add(name)
            self._conf_version += 1
            self._entry_time[name] = self._time
            self._idle_time[name] = self._time
            if self._listeners:
                self._notify("state entered", name, state=name)

        for event in sent_events:
            self._raise_event(event)  # type: ignore[arg-type]
            self._sent_events.append(event)

        # stock returns a copy of the step with the events sent; the step, made for this call
        # by _create_steps or _create_stabilization_step, is that copy
        step.sent_events = sent_events
        return step
