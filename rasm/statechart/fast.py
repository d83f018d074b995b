"""A faster sismic interpreter with exactly the stock semantics.

:class:`FastInterpreter` subclasses :class:`sismic.interpreter.Interpreter` and overrides its
private step machinery. It takes the same decisions in the same order (same macro and micro steps,
same guard, action and contract evaluations, same meta-events, same errors and messages); only the
bookkeeping is cheaper:

- tree queries (ancestors, descendants, depth, least common ancestor) come from tables computed
  once per chart (:mod:`rasm.statechart.fast_tables`);
- transitions are looked up in an index by event name, already in stock selection order;
- the pairwise conflict check of simultaneous transitions is cached per pair;
- the sorted configuration is cached until the configuration changes;
- contract evaluation is skipped for objects that declare no contract (with sismic's evaluators,
  whose contract methods then do nothing at all);
- meta-events are not built when nobody listens;
- a bound property statechart is executed only for the meta-events it could react to (see
  :class:`PropertyListener`).

Attributes keep the names, types and meaning of stock sismic (``_configuration``, ``_memory``,
``_time``, queues, ...), so code that snapshots and restores them keeps working: the cached
configuration order is keyed by the identity of the ``_configuration`` set and a version counter
bumped at each change this class makes.
"""

from __future__ import annotations

import bisect
import warnings
from collections.abc import Callable, Iterable
from itertools import combinations
from typing import Any

from sismic.clock import SynchronizedClock
from sismic.code import Evaluator, PythonEvaluator
from sismic.exceptions import (
    ConflictingTransitionsError,
    NonDeterminismError,
    PropertyStatechartError,
)
from sismic.interpreter import Interpreter
from sismic.interpreter.listener import PropertyStatechartListener
from sismic.model import (
    Event,
    InternalEvent,
    MacroStep,
    MetaEvent,
    MicroStep,
    Statechart,
    Transition,
)

from rasm.statechart import fast_tables as ft
from rasm.statechart.meta_guards import DISCRIMINANT, MISSING, NO_EVENT, guard_predicate

__all__ = ["PURE_GUARD_EVALUATIONS", "FastInterpreter", "PropertyListener"]

#: ``evaluate_guard`` implementations that evaluate a guard's code and nothing else (sismic's,
#: and the platform's evaluators register theirs): with them, a guard decided from the
#: meta-event's discriminant (:mod:`rasm.statechart.meta_guards`) need not be evaluated.
PURE_GUARD_EVALUATIONS: set[Callable[..., bool]] = {PythonEvaluator.evaluate_guard}

def _data_attribute(key: str) -> property:
    def read(event: Event) -> Any:
        try:
            return event.data[key]
        except KeyError:  # Event.__getattr__'s error, word for word
            raise AttributeError(f"{event} has no attribute {key}") from None

    return property(read)


class _Meta(MetaEvent):
    """The meta-events this interpreter raises: a MetaEvent whose data keys are read without
    going through ``Event.__getattr__`` (a failed attribute lookup first, then the call: most of
    the cost of a property guard like ``event.state == 'idle'``). Same values (read live from
    ``data``), same errors, same repr, equality and hash; copied and pickled as a MetaEvent."""

    __slots__ = ()
    state = _data_attribute("state")
    event = _data_attribute("event")
    source = _data_attribute("source")
    target = _data_attribute("target")
    time = _data_attribute("time")

    def __reduce_ex__(self, protocol: Any) -> tuple:
        return (MetaEvent, (self.name,), (self.name, self.data))


# Named as stock's class, for repr (which prints the class name) and for whoever prints the type.
_Meta.__name__ = _Meta.__qualname__ = MetaEvent.__name__
_Meta.__module__ = MetaEvent.__module__

# Event classes whose ``delay`` can only come from their data (no attribute, no __getattr__
# override): reading ``data`` directly avoids the exception stock ``getattr`` goes through.
_PLAIN_EVENTS = (Event, InternalEvent, MetaEvent, _Meta)


def _delay(event: Event) -> Any:
    if type(event) in _PLAIN_EVENTS:
        return event.data.get("delay", 0)
    return getattr(event, "delay", 0)


def _has_delay(event: Event) -> bool:
    if type(event) in _PLAIN_EVENTS:
        return "delay" in event.data
    return hasattr(event, "delay")


def _name_of(event: Event) -> Any:
    """An event's name as a guard reading ``event.event.name`` sees it; None (undecided) when
    reading it could raise or run code."""
    return event.name if type(event) in _PLAIN_EVENTS and type(event.name) is str else None


def _source_of(transition: Transition) -> str:
    """``transition.source``: sismic's property returns ``_source``, read directly (steps and
    guard timers read it at every step); a subclass's own property is asked."""
    return transition._source if type(transition) is Transition else transition.source


def _target_of(transition: Transition) -> str | None:
    """``transition.target``, as :func:`_source_of` reads the source."""
    return transition._target if type(transition) is Transition else transition.target


_new_object = object.__new__


def _micro_step(
    event: Event | None = None,
    transition: Transition | None = None,
    entered: list[str] | None = None,
    exited: list[str] | None = None,
    sent: list[Event] | None = None,
) -> MicroStep:
    """``MicroStep(event, transition, entered, exited, sent)``: the same slots set to the same
    values, without the Python-level ``__init__`` (a call with keywords costs several times the
    object, and steps make several per macro step)."""
    step = _new_object(MicroStep)
    step.event = event
    step.transition = transition
    step.entered_states = entered if entered else []
    step.exited_states = exited if exited else []
    step.sent_events = sent if sent else []
    return step


def _event(name: str, data: dict[str, Any]) -> Event:
    """``Event(name, **data)`` for a ``data`` dict nobody else holds (a ``**parameters``),
    without the Python-level ``__init__`` (see _micro_step)."""
    event = _new_object(Event)
    event.name = name
    event.data = data
    return event


def _macro_step(time: float, steps: list[MicroStep]) -> MacroStep:
    """``MacroStep(time, steps)`` without the Python-level ``__init__`` (see _micro_step)."""
    macro = _new_object(MacroStep)
    macro._time = time
    macro._steps = steps
    return macro


def _standard_contracts(evaluator: Evaluator) -> bool:
    """True if the evaluator's contract methods are sismic's own (so no-contract means no-op)."""
    klass = type(evaluator)
    return all(
        getattr(klass, name) in (getattr(PythonEvaluator, name), getattr(Evaluator, name))
        for name in ("evaluate_preconditions", "evaluate_postconditions", "evaluate_invariants")
    )


def _standard_actions(evaluator: Evaluator) -> bool:
    """True if entry/exit actions go through sismic's base methods (no code means no call)."""
    klass = type(evaluator)
    return (
        klass.execute_on_entry is Evaluator.execute_on_entry
        and klass.execute_on_exit is Evaluator.execute_on_exit
    )


def _scan(
    entries: tuple,
    event: Event | None,
    states: set[str],
    selected: list[Transition],
    evaluate_guard: Callable[..., bool],
) -> None:
    """Stock selection over one group of the index (deepest source first, priority classes
    highest first): the transitions whose guard holds, in order, appended to ``selected``."""
    ignored: set[str] | tuple = ()  # sources (and their ancestors) that already fired
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
                if not ignored:
                    ignored = set()
                ignored.update(ancestors)
                ignored.add(source)
                break


class FastInterpreter(Interpreter):
    """Drop-in replacement for :class:`sismic.interpreter.Interpreter`, several times faster.

    Same constructor, public API and semantics. The statechart must not be modified while an
    interpreter runs it (tables are rebuilt for interpreters created after an edit).
    """

    # The attributes a step reads and writes (stock's, then this class's) are slots: a slot is
    # read and written without the instance dict lookup (most of what an attribute access costs,
    # compiled), and keeps its name, value and meaning. The instance still has a ``__dict__``
    # (stock's class has one) for anything else.
    __slots__ = (
        "_ignore_contract", "_statechart", "_initialized", "clock", "_time", "_memory",
        "_configuration", "_entry_time", "_idle_time", "_sent_events", "_internal_queue",
        "_external_queue", "_listeners", "_evaluator",
        "_tables", "_conf_version", "_step_count", "_conf_cache_key", "_conf_cache",
        "_reactive_key", "_reactive", "_fast_events", "_contracts_possible", "_preselected",
        "_fold", "_fast_contracts", "_skip_noop_actions", "_skip_noop_transitions",
    )

    def __init__(
        self,
        statechart: Statechart,
        *,
        evaluator_klass: Callable[..., Evaluator] = PythonEvaluator,
        initial_context: Any = None,
        clock: Any = None,
        ignore_contract: bool = False,
    ) -> None:
        # Set before the stock constructor: it runs the preamble, which may call active().
        self._tables = ft.tables_for(statechart)
        self._conf_version = 0
        self._step_count = 0  # execute_once calls: PropertyListener.needs checks once per step
        self._conf_cache_key: tuple[Any, int, int] | None = None
        self._conf_cache: list[str] = []
        self._reactive_key: tuple[Any, int, int] | None = None
        self._reactive: frozenset[str] = frozenset()
        self._fast_events = False
        self._contracts_possible = True
        self._preselected: tuple[Event, list[Transition]] | None = None
        self._fold = _ListenerGroups()
        super().__init__(
            statechart,
            evaluator_klass=evaluator_klass,
            initial_context=initial_context,
            clock=clock,
            ignore_contract=ignore_contract,
        )
        klass = type(self)
        # Skipping a call is only equivalent when the callee is the one this module knows.
        self._fast_events = klass._raise_event is FastInterpreter._raise_event
        self._fast_contracts = (
            klass._evaluate_contract_conditions is FastInterpreter._evaluate_contract_conditions
            and _standard_contracts(self._evaluator)
        )
        # Whether any contract evaluation can do something (``_ignore_contract`` is read live).
        self._contracts_possible = self._tables.has_contracts or not self._fast_contracts
        self._skip_noop_actions = _standard_actions(self._evaluator)
        # sismic's execute_action returns [] for a transition without action: not called then
        self._skip_noop_transitions = (
            type(self._evaluator).execute_action is Evaluator.execute_action
        )

    def __repr__(self) -> str:
        # Stock text for this class itself, so that messages embedding the repr of a property
        # interpreter (PropertyStatechartError) read exactly as with stock sismic.
        name = "Interpreter" if type(self) is FastInterpreter else type(self).__name__
        return f"{name}({self._statechart!r})"

    # ---- public API -----------------------------------------------------------------------

    def attach(self, listener: Callable[[MetaEvent], Any]) -> None:
        super().attach(listener)
        self._fold.step = -1  # what the listeners did as a group is not what they do now

    def detach(self, listener: Callable[[MetaEvent], Any]) -> None:
        super().detach(listener)
        self._fold.step = -1

    @property
    def configuration(self) -> list[str]:
        """Active state names ordered by depth, ties broken by name (as stock sismic)."""
        conf = self._configuration
        key = (conf, self._conf_version, len(conf))
        cached = self._conf_cache_key
        # ``is`` on the set itself (held by the key, so its id cannot be reused) detects the
        # attribute being reassigned, e.g. by a snapshot restore.
        if cached is None or cached[0] is not conf or cached[1:] != key[1:]:
            table = self._tables.config_key
            try:
                self._conf_cache = sorted(conf, key=table.__getitem__)
            except KeyError:  # an unknown name: let stock raise its StatechartError
                return super().configuration
            self._conf_cache_key = key
        return list(self._conf_cache)

    def bind_property_statechart(
        self,
        statechart: Statechart,
        *,
        interpreter_klass: Callable | None = None,
    ) -> Callable[[MetaEvent], Any]:
        """Bind a property statechart, executed by a :class:`FastInterpreter` by default.

        Same behaviour as stock sismic; the returned listener is a :class:`PropertyListener`,
        which skips the meta-events the property statechart cannot react to.
        """
        if isinstance(statechart, Interpreter):
            return super().bind_property_statechart(statechart)
        klass = FastInterpreter if interpreter_klass is None else interpreter_klass
        listener = PropertyListener(klass(statechart, clock=SynchronizedClock(self)))
        self.attach(listener)
        return listener

    def reactive_events(self) -> frozenset[str]:
        """Names of the events some transition of an active state listens to."""
        conf = self._configuration
        key = self._reactive_key
        if key is None or key[0] is not conf or key[1] != self._conf_version or key[2] != len(conf):
            events_from = self._tables.events_from
            found: set[str] = set()
            for name in conf:
                found |= events_from.get(name, frozenset())
            self._reactive = frozenset(found)
            self._reactive_key = (conf, self._conf_version, len(conf))
        return self._reactive

    # ---- macro step -----------------------------------------------------------------------

    def execute_once(self) -> MacroStep | None:
        """Stock ``execute_once`` with cheap contract and meta-event bookkeeping."""
        self._time = now = self.clock.time
        self._step_count += 1
        self._sent_events.clear()
        if self._idle_step_possible and self._idle_now(now):
            return None
        fast_events = self._fast_events
        if not fast_events:
            self._raise_event(_Meta("step started", time=self._time))
        elif self._listeners and not self._fold.start(self):
            self._announce("step started", None, {"time": self._time})

        computed_steps = self._compute_steps()

        if len(computed_steps) > 0:
            if computed_steps[0].event is not None:
                event = self._select_event(consume=True)
                if not fast_events:
                    self._raise_event(_Meta("event consumed", event=event))
                elif self._listeners:
                    self._announce("event consumed", _name_of(event), {"event": event})
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
            macro_step: MacroStep | None = _macro_step(self._time, executed_steps)
        else:
            macro_step = None

        if self._contracts_possible and not self._ignore_contract:
            self._check_invariants(macro_step)

        if not fast_events:
            self._raise_event(_Meta("step ended"))
        elif self._listeners:
            self._announce("step ended", None, {})
        return macro_step

    # Whether this class selects steps as FastInterpreter does (set per subclass), so that
    # _idle_now may answer for _compute_steps.
    _idle_step_possible = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._idle_step_possible = all(
            getattr(cls, name) is getattr(FastInterpreter, name)
            for name in ("_compute_steps", "_select_event", "_select_transitions")
        )

    def _idle_now(self, now: float) -> bool:
        """True when a step at ``now`` has nothing to do and nobody to tell: no listener, no
        event due, no eventless transition, no invariant to check. Stock then finds no step,
        checks no contract and raises meta-events nobody hears: the step returns None."""
        if (
            self._listeners
            or not self._fast_events  # a subclass's _raise_event sees every meta-event
            or not self._initialized
            or not self._tables.event_driven
        ):
            return False
        if self._contracts_possible and not self._ignore_contract:
            return False
        internal, external = self._internal_queue, self._external_queue
        return not (internal and internal[0][0] <= now) and not (external and external[0][0] <= now)

    def _compute_steps(self) -> list[MicroStep]:
        """Stock ``_compute_steps``, word for word (here so that it runs compiled, with the
        micro steps built as :func:`_micro_step` builds them)."""
        if not self._initialized:
            self._initialized = True
            return [_micro_step(entered=[self._statechart.root])]  # type: ignore[list-item]
        event = self._select_event()
        transitions = self._select_transitions(event, states=self._configuration)
        if len(transitions) == 0:
            # no event, no step; or an empty step, so that the event is consumed
            return [] if event is None else [_micro_step(event)]
        transitions = self._sort_transitions(transitions)
        event = None if transitions[0].event is None else event
        return self._create_steps(event, transitions)

    def _stabilize(self) -> list[MicroStep]:
        """Stock ``_stabilize``, word for word (here so that it runs compiled)."""
        steps = []
        step = self._create_stabilization_step(self._configuration)
        while step is not None:
            steps.append(self._apply_step(step))
            step = self._create_stabilization_step(self._configuration)
        return steps

    def _check_invariants(self, macro_step: MacroStep | None) -> None:
        if self._contracts_possible and not self._ignore_contract:
            states = self._tables.state
            wanted = self._tables.invariant_states if self._fast_contracts else None
            for name in self.configuration:
                if wanted is None or name in wanted:
                    state = states[name] if name in states else self._statechart.state_for(name)
                    self._evaluate_contract_conditions(state, "invariants", macro_step)

    def _consume(self, event: Event, transitions: list[Transition], now: float) -> MacroStep:
        """``queue(event)`` then ``execute_once()`` at ``now``, for an interpreter without
        listeners whose queues hold nothing due at ``now`` and whose selection for ``event`` is
        ``transitions`` (non-empty, all listening to it): the event would be queued first in line
        and consumed at once, so it is not queued at all. Same steps, state and errors."""
        before = self._time
        self._time = now
        self._sent_events.clear()
        try:
            steps = self._create_steps(event, self._sort_transitions(transitions))
        except BaseException:
            # stock queued the event (at the time before the step) before computing the steps
            self._time = before
            self._queue_event(event)
            self._time = now
            raise
        if hasattr(self._evaluator, "on_step_starts"):
            warnings.warn(  # noqa: B028 (stock's warning, same stack level)
                "Evaluator.on_step_starts is deprecated since 1.4.0.", DeprecationWarning
            )
            self._evaluator.on_step_starts(event)
        executed_steps = []
        for step in steps:
            executed_steps.append(self._apply_step(step))
            executed_steps.extend(self._stabilize())
        macro_step = _macro_step(self._time, executed_steps)
        self._check_invariants(macro_step)
        return macro_step

    def _evaluate_contract_conditions(
        self,
        obj: Any,
        cond_type: str,
        step: MacroStep | MicroStep | None = None,
    ) -> None:
        """Stock contract check, skipped where sismic's evaluator would find nothing to check."""
        if self._ignore_contract:
            return
        if self._fast_contracts:
            tables = self._tables
            needs = {
                "preconditions": tables.needs_pre,
                "postconditions": tables.needs_post,
                "invariants": tables.needs_inv,
            }[cond_type]
            if id(obj) not in needs:
                return
        super()._evaluate_contract_conditions(obj, cond_type, step)

    # ---- events ---------------------------------------------------------------------------

    def queue(self, event_or_name: str | Event, *event_or_names: str | Event, **parameters: Any):
        """Stock ``queue``; one event by name or instance goes straight to the queue."""
        if event_or_names:
            return super().queue(event_or_name, *event_or_names, **parameters)
        if isinstance(event_or_name, str):
            event_or_name = _event(event_or_name, parameters)  # (a new dict at every call)
        self._queue_event(event_or_name)
        return self

    def _queue_event(self, event: Event) -> None:
        """Stock queueing; appends directly when the event goes last (the usual case)."""
        internal = isinstance(event, InternalEvent)
        queue: list = self._internal_queue if internal else self._external_queue
        time = self._time + _delay(event)
        if queue:
            last_time, last_event = queue[-1]
            # bisect_right on (time, not internal): equal keys go after, hence <=.
            if (last_time, not isinstance(last_event, InternalEvent)) > (time, not internal):
                keys = [(t, not isinstance(e, InternalEvent)) for t, e in queue]
                queue.insert(bisect.bisect_right(keys, (time, not internal)), (time, event))
                return
        queue.append((time, event))

    def _raise_event(self, event: InternalEvent | MetaEvent) -> None:
        """Stock ``_raise_event``; meta-events about a sent event are built only if heard."""
        if isinstance(event, InternalEvent):
            self._queue_event(event)
            if not self._fast_events:
                self._raise_event(_Meta("event sent", event=event))
                if _has_delay(event):
                    self._raise_event(_Meta("delayed event sent", event=event))
            elif self._listeners:
                name = _name_of(event)
                self._announce("event sent", name, {"event": event})
                if _has_delay(event):
                    self._announce("delayed event sent", name, {"event": event})
        elif isinstance(event, MetaEvent):
            for listener in self._listeners:
                listener(event)
        else:
            super()._raise_event(event)

    def _announce(self, name: str, value: Any, data: dict[str, Any]) -> None:
        """Raise the meta-event ``name`` (``data``; ``value`` its discriminant, see
        :mod:`rasm.statechart.meta_guards`) to every listener, as stock does, built only if one
        of them may react: a :class:`PropertyListener` that says it would do nothing with it is
        passed over (delivering would be a no-op).

        What the listeners did with a meta-event is remembered (see :class:`_ListenerGroup`):
        when they are where they were then, it is done again in one lookup."""
        fold = self._fold
        step = self._step_count
        group = fold.group if fold.step == step else None
        if group is not None:
            move = group.moves.get((name, value))
            if move is not None:
                ops, after, watched = move
                if watched:
                    # the context names the interests reached read must still be bound as they
                    # were (the group's own were checked in this step; no property code ran)
                    for listener, _, target in ops:
                        if not listener._watch_holds(target):
                            move = None
                            break
            if move is not None:
                fold.group = after
                now = self._time
                for listener, effect, target in ops:
                    interp = listener._interpreter
                    hook = listener.before_state_change or listener.before_change
                    if hook is not None:
                        hook(interp)
                    _replay(interp, effect, now)
                    listener._interest_at = (target, interp._configuration, interp._conf_version)
                    listener._checked = target
                return
        meta = None
        ops = []  # (listener, effect replayed, interest after) of each delivery
        for listener in self._listeners:
            if type(listener) is PropertyListener:
                if not listener.needs(name, value):
                    continue
                if meta is None:
                    meta = _Meta(name, **data)
                effect = listener.deliver(meta, value)
                if effect is None or ops is None:
                    ops = None
                else:
                    ops.append((listener, effect, listener._checked))
                continue
            ops = None
            if meta is None:
                meta = _Meta(name, **data)
            listener(meta)
        if ops is not None:
            fold.remember(self, group, name, value, ops)
        else:
            fold.step = -1

    def _select_event(self, *, consume: bool = False) -> Event | None:
        """Next event to process: internal queue first, then external (as stock)."""
        now = self._time
        queue = self._internal_queue
        if not (queue and queue[0][0] <= now):
            queue = self._external_queue
            if not (queue and queue[0][0] <= now):
                return None
        event = queue[0][1]
        if consume:
            queue.pop(0)
        return event

    # ---- transition selection ---------------------------------------------------------------

    def _select_transitions(
        self,
        event: Event | None,
        states: set[str],
        *,
        eventless_first: bool = True,
        inner_first: bool = True,
    ) -> list[Transition]:
        """Stock selection (eventless first, inner-first, priorities) from the event index."""
        preselected = self._preselected
        if preselected is not None and preselected[0] is event:
            # chosen by a PropertyListener just before, on this configuration, context and time
            self._preselected = None
            return list(preselected[1])
        tables = self._tables
        if not (eventless_first and inner_first and tables.selection_ok):
            return super()._select_transitions(
                event, states, eventless_first=eventless_first, inner_first=inner_first
            )
        name = getattr(event, "name", None)
        selection = tables.selection
        selected: list[Transition] = []
        evaluate_guard = self._evaluator.evaluate_guard
        entries = selection.get(None)
        if entries:
            _scan(entries, None, states, selected, evaluate_guard)
            if selected:
                return selected
        if name is not None:
            entries = selection.get(name)
            if entries:
                _scan(entries, event, states, selected, evaluate_guard)
        return selected

    def _sort_transitions(self, transitions: list[Transition]) -> list[Transition]:
        """Stock order and conflict checks, with the pairwise verdicts cached per chart."""
        if len(transitions) > 1:
            tables = self._tables
            for t1, t2 in combinations(transitions, 2):
                verdict = tables.pair_verdict(t1, t2)
                if verdict == ft.PAIR_OK:
                    continue
                if verdict == ft.PAIR_NO_LCA:
                    self._statechart.state_for(None)  # type: ignore[arg-type]  # raises
                klass = (
                    NonDeterminismError
                    if verdict == ft.PAIR_NON_DETERMINISM
                    else ConflictingTransitionsError
                )
                what = (
                    "Non-determinist choice between transitions"
                    if verdict == ft.PAIR_NON_DETERMINISM
                    else "Conflicting transitions:"
                )
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
        """One micro step per transition, from the precomputed exit/entry lists."""
        steps = []
        conf = self._configuration
        steps_for = self._tables.steps_for
        for transition in transitions:
            if _target_of(transition) is None:
                steps.append(_micro_step(event, transition))
                continue
            exits, entered = steps_for(transition)
            steps.append(
                _micro_step(event, transition, list(entered), [s for s in exits if s in conf])
            )
        return steps

    # ---- stabilisation --------------------------------------------------------------------

    def _create_stabilization_step(self, names: Iterable[str]) -> MicroStep | None:
        """Stock stabilisation: act on the deepest (then first by name) actionable leaf."""
        tables = self._tables
        active = names if isinstance(names, (set, frozenset)) else set(names)
        kinds = tables.stabilization
        source_key = tables.source_key
        descendant_set = tables.descendant_set
        best = None
        best_key = None
        for name in active:
            if name not in kinds:
                if name not in tables.state:
                    return super()._create_stabilization_step(names)  # stock raises
                continue
            if not active.isdisjoint(descendant_set[name]):
                continue  # not a leaf
            key = source_key[name]
            if best_key is None or key < best_key:
                best, best_key = name, key
        if best is None:
            return None
        kind = kinds[best]
        if kind == ft.FINAL_CHILD_OF_ROOT:
            return _micro_step(exited=[best, tables.root])  # type: ignore[list-item]
        if kind == ft.HISTORY:
            states_to_enter = self._memory.get(best, [tables.state[best].memory])  # type: ignore
            depth = tables.depth
            chart = self._statechart
            states_to_enter.sort(  # type: ignore[union-attr]
                key=lambda x: (depth[x] if x in depth else chart.depth_for(x), x)
            )
            return _micro_step(entered=states_to_enter, exited=[best])
        if kind == ft.PARALLEL:
            return _micro_step(entered=list(tables.parallel_children[best]))
        return _micro_step(entered=[tables.state[best].initial])  # type: ignore

    # ---- micro step -----------------------------------------------------------------------

    def _apply_step(self, step: MicroStep) -> MicroStep:
        """Apply a micro step: same calls, same order, same meta-events as stock sismic."""
        tables = self._tables
        table = tables.state
        chart = self._statechart
        entered_names = step.entered_states
        exited_names = step.exited_states
        if tables.names_plain:
            # each state's name is the name it is known by: the names are used as they are, and
            # the states looked up only where they are needed (unknown names go through
            # state_for first, which raises stock's StatechartError)
            for names in (entered_names, exited_names):
                for n in names:
                    if n not in table:
                        chart.state_for(n)
            entered_states = exited_states = None
        else:
            entered_states = [table[n] if n in table else chart.state_for(n) for n in entered_names]
            exited_states = [table[n] if n in table else chart.state_for(n) for n in exited_names]
            entered_names = [state.name for state in entered_states]
            exited_names = [state.name for state in exited_states]
        entry_code, exit_code = tables.entry_code, tables.exit_code

        conf = self._configuration
        history = tables.history_children
        active_configuration = set(conf) if history else conf  # copy only if memory may need it
        evaluator = self._evaluator
        check = self._contracts_possible and not self._ignore_contract
        fast_events = self._fast_events
        skip_noop = self._skip_noop_actions
        now = self._time
        sent_events: list[Event] = []

        for index, name in enumerate(exited_names):
            state = table[name] if exited_states is None else exited_states[index]
            if not skip_noop or name in exit_code:
                sent_events.extend(evaluator.execute_on_exit(state))
            if name in history:
                for child, deep in history[name]:
                    if deep:
                        active = active_configuration.intersection(tables.descendants[name])
                        # Stock's asserts, spelt out: pytest rewrites asserts of plugin packages
                        # (rasm is one), which would change the exception's message.
                        if __debug__ and not len(active) >= 1:
                            raise AssertionError
                    else:
                        active = active_configuration.intersection(tables.children[name])
                        if __debug__ and not len(active) == 1:
                            raise AssertionError
                    self._memory[child] = list(active)
            conf.remove(name)
            self._conf_version += 1
            if check:
                self._evaluate_contract_conditions(state, "postconditions", step)
            if not fast_events:
                self._raise_event(_Meta("state exited", state=name))
            elif self._listeners:
                self._announce("state exited", name, {"state": name})

        transition = step.transition
        if transition:
            if check:
                self._evaluate_contract_conditions(transition, "preconditions", step)
                self._evaluate_contract_conditions(transition, "invariants", step)
            if not self._skip_noop_transitions or transition.action:
                sent_events.extend(evaluator.execute_action(transition, step.event))
            if check:
                self._evaluate_contract_conditions(transition, "postconditions", step)
                self._evaluate_contract_conditions(transition, "invariants", step)
            source, target = _source_of(transition), _target_of(transition)
            self._idle_time[source] = now
            if not fast_events or self._listeners:
                inner = step.event
                data = {"source": source, "target": target, "event": inner}
                if not fast_events:
                    self._raise_event(_Meta("transition processed", **data))
                else:
                    self._announce(
                        "transition processed", NO_EVENT if inner is None else _name_of(inner), data
                    )

        for index, name in enumerate(entered_names):
            state = table[name] if entered_states is None else entered_states[index]
            if check:
                self._evaluate_contract_conditions(state, "preconditions", step)
            if not skip_noop or name in entry_code:
                sent_events.extend(evaluator.execute_on_entry(state))
            conf.add(name)
            self._conf_version += 1
            self._entry_time[name] = now
            self._idle_time[name] = now
            if not fast_events:
                self._raise_event(_Meta("state entered", state=name))
            elif self._listeners:
                self._announce("state entered", name, {"state": name})

        for event in sent_events:
            self._raise_event(event)  # type: ignore[arg-type]
            self._sent_events.append(event)

        return _micro_step(
            step.event, step.transition, step.entered_states, step.exited_states, sent_events
        )


class _Interest:
    """What a property listener knows about one set of active states of its property: which
    meta-events it could react to, the guard predicates, the selections they make, and the
    context names (and the objects they were bound to) all of that read."""

    __slots__ = (
        "effects", "eventless", "listening", "predicates", "quiet_start", "selections", "targets",
        "watch",
    )

    def __init__(self, eventless: bool = False) -> None:
        self.eventless = eventless  # whether an active state has an eventless transition
        # listening["step started"] is False: known that no active transition listens to it
        self.quiet_start = False
        self.effects: dict[tuple[str, str], tuple] = {}
        self.listening: dict[str, bool | dict[Any, bool]] = {}
        self.predicates: dict[str, list[tuple[Transition, Any]]] = {}
        self.selections: dict[tuple[str, str], tuple[Transition, ...]] = {}
        # per remembered effect, the interest of the states it leads to
        self.targets: dict[tuple[str, str], _Interest] = {}
        self.watch: dict[str, Any] = {}


class _ListenerGroup:
    """The property listeners of an interpreter, each checked in the current step and known
    to be in one :class:`_Interest`: ``moves`` maps a meta-event (name, discriminant) to what
    delivering it did when they were so (nothing but remembered effects replayed), the group
    they were in after, and whether the interests reached watch context names that those of
    this group do not (bound to the same objects): only those need checking on the way."""

    __slots__ = ("interests", "moves")

    def __init__(self, interests: tuple[_Interest, ...]) -> None:
        self.interests = interests
        self.moves: dict[tuple[str, Any], tuple[tuple, _ListenerGroup, bool]] = {}


class _ListenerGroups:
    """An interpreter's :class:`_ListenerGroup` memo, and the group its listeners are in during
    step ``step`` (any other step: unknown)."""

    __slots__ = ("group", "groups", "step")

    # Interests are replaced when a watched name is rebound: the memo is dropped past this.
    LIMIT = 1024

    def __init__(self) -> None:
        self.step = -1
        self.group: _ListenerGroup | None = None
        self.groups: dict[tuple[_Interest, ...], _ListenerGroup] = {}

    def remember(
        self, interp: FastInterpreter, before: _ListenerGroup | None, name: str, value: Any,
        ops: list[tuple[PropertyListener, tuple, _Interest]],
    ) -> None:
        """After the listeners of ``interp`` (all property listeners) took meta-event ``name``
        from group ``before`` (None: unknown) by replaying ``ops``: remember that, and where
        they are now."""
        step = interp._step_count
        key = []
        for listener in interp._listeners:
            checked = listener._checked
            if (
                checked is None
                or listener._checked_step != step
                or listener._step_source is not interp
            ):
                self.step = -1
                return
            key.append(checked)
        after = self._group_of(tuple(key))
        # a sent event's meta-events may carry a delay, which deliver() never replays
        if before is not None and name != "event sent" and name != "delayed event sent":
            # The group's own interests are checked whenever it is reached (see _announce):
            # a name an interest reached watches, bound to the same object, needs no new check.
            # (the same listeners: attach() and detach() forget the group)
            start = dict(zip(interp._listeners, before.interests, strict=True))
            watched = any(
                start[listener].watch.get(watched_name, _UNSEEN) is not bound
                for listener, _, target in ops
                for watched_name, bound in target.watch.items()
            )
            before.moves[(name, value)] = (tuple(ops), after, watched)
        self.step, self.group = step, after

    def _group_of(self, interests: tuple[_Interest, ...]) -> _ListenerGroup:
        groups = self.groups
        group = groups.get(interests)
        if group is None:
            if len(groups) >= self.LIMIT:
                groups.clear()
            group = groups[interests] = _ListenerGroup(interests)
        return group

    def start(self, interp: FastInterpreter) -> bool:
        """Announce ``step started`` (the step's first meta-event) when no listener of ``interp``
        can react to it, doing for each what :meth:`PropertyListener.needs` does then: check
        that it is settled, nothing queued, its states and the names they read as remembered
        and nothing time-triggered to evaluate, then move its time. False, having changed
        nothing, when that is not so for one of them (``needs`` then decides, one by one)."""
        now = interp._time
        interests = []
        moved = []  # the listeners whose property's time moves
        # This runs at every step of a chart with property statecharts: each check reads as few
        # attributes as it can (an attribute read is most of what it costs, compiled).
        for listener in interp._listeners:
            # _starter: interp, for a settled PropertyListener it steps with static guards
            if type(listener) is not PropertyListener or listener._starter is not interp:
                return False
            prop = listener._interpreter
            conf = prop._configuration
            if prop._listeners or prop._internal_queue or prop._external_queue or not conf:
                return False
            interest, interest_conf, version = listener._interest_at
            if conf is not interest_conf or prop._conf_version != version:
                return False
            watch = interest.watch
            if watch:
                # _watch_holds() without the call; a name rebound is left to needs(), which
                # finds it again and forgets what it remembered
                context = listener._context
                for name, bound in watch.items():
                    if context.get(name, MISSING) is not bound:
                        return False
            if prop._time != now:
                if interest.eventless:
                    return False
                moved.append(listener)
            if not interest.quiet_start:
                return False
            interests.append(interest)
        step = interp._step_count
        for listener in moved:
            prop = listener._interpreter
            hook = listener.before_time_change or listener.before_change
            if hook is not None:
                hook(prop)
            prop._time = now
        listeners = interp._listeners
        for index in range(len(interests)):  # (zip(..., strict=True) is a call with keywords)
            listeners[index]._checked, listeners[index]._checked_step = interests[index], step
        self.step, self.group = step, self._group_of(tuple(interests))
        return True


_UNSEEN = object()  # not a name a watch has (MISSING is a binding a watch can record)


def _decidable(value: Any) -> bool:
    """Whether guard predicates can decide for this discriminant (None: unknown)."""
    return type(value) is str or value is NO_EVENT


def _discriminant(event: MetaEvent) -> Any:
    """The value guards of ``event``'s name read (see meta_guards), None when there is none."""
    data = event.data
    if "state" in data:
        return data["state"] if event.name in ("state entered", "state exited") else None
    if "event" not in data:
        return None
    inner = data["event"]
    if inner is None:
        return NO_EVENT if event.name == "transition processed" else None
    return _name_of(inner)


def _replay(interp: FastInterpreter, effect: tuple, now: float) -> None:
    """Apply a remembered effect (see PropertyListener._effect_of) at ``now``: the same changes
    as the execution it was remembered from, without the step machinery. (A function, not a
    method: it needs no listener, and a call makes no bound method.)"""
    exited, sources, entered = effect
    interp._time = now
    interp._sent_events.clear()
    conf = interp._configuration
    for name in exited:
        conf.remove(name)
    idle = interp._idle_time
    for name in sources:
        idle[name] = now
    entry = interp._entry_time
    for name in entered:
        conf.add(name)
        entry[name] = now
        idle[name] = now
    interp._conf_version += len(exited) + len(entered)


class PropertyListener(PropertyStatechartListener):
    """Feeds meta-events to a property statechart, skipping the executions that would do nothing.

    Stock sismic queues every meta-event to the property interpreter and executes it. When the
    property interpreter is *settled* (its last execution completed, nothing is due in its
    queues), an execution for a meta-event can only do something if

    - a transition of an active state listens to the event's name and its guard holds (the
      guards are evaluated here, once: the step then reuses the selection), or
    - the time moved since the last execution and an active state has an eventless transition
      (``after``, ``idle``, time guards), which the execution would evaluate anew.

    Otherwise the execution would consume the event in an empty step and record the time; the
    listener records the time (:attr:`before_change` is called first, as for a real execution)
    and skips the rest. A guard that raises is left to the real execution, which raises it again
    with the event queued, as stock does.

    Skipping is disabled when it could be observed: a property chart with invariants (they see
    the consumed event), a property interpreter with listeners of its own, or one that is not a
    :class:`FastInterpreter` using sismic's Python evaluator (or a subclass of it). Guards are
    assumed free of side effects, and guards of eventless transitions to depend only on the
    property's own context, configuration and time. Delayed meta-events are always delivered
    (they wait in the property's queue).

    Under the same conditions, the closing step of an execution (the one that finds nothing to
    do) is not run when no active state has an eventless transition and no event is queued.
    """

    # Slots, as FastInterpreter's (read at every meta-event of the bound interpreter's steps).
    __slots__ = (
        "_interpreter", "_settled", "_starter", "_can_skip", "_eventless_sources", "_names",
        "_time_source", "_interests", "_interest_at", "_context", "_consume_directly",
        "_effects_possible", "_selection_key", "_step_source", "_checked", "_checked_step",
        "_static_guards",
    )

    #: Called with the property's interpreter just before the listener changes it (a meta-event
    #: that is not skipped, or the time a skipped one records); the platform's atomic layer
    #: snapshots the property there.
    before_change: Callable[[Interpreter], Any] | None = None
    #: Called instead of :attr:`before_change` when the listener only moves the property's time
    #: (a skipped meta-event at a new time); the atomic layer then saves just the time.
    before_time_change: Callable[[Interpreter], Any] | None = None
    #: Called instead of :attr:`before_change` before a remembered effect is replayed (it only
    #: changes the configuration, entry and idle times and time, see :func:`_replay`).
    before_state_change: Callable[[Interpreter], Any] | None = None

    def __init__(self, interpreter: Interpreter) -> None:
        super().__init__(interpreter)
        self._settled = False
        # the interpreter whose steps may announce `step started` to this listener in one pass
        # (_ListenerGroups.start): its bound interpreter while settled with static guards
        self._starter: Interpreter | None = None
        self._can_skip = (
            isinstance(interpreter, FastInterpreter)
            and isinstance(interpreter._evaluator, PythonEvaluator)
            and not interpreter._tables.invariant_states
        )
        # States with an eventless transition: while none is active and nothing is queued, the
        # step after an event is a no-op (no listeners, no invariants), so it is not run.
        self._eventless_sources = frozenset(
            t.source for t in interpreter.statechart.transitions if t.event is None
        )
        # the event names some transition of the property listens to, in any state
        self._names = frozenset(
            t.event for t in interpreter.statechart.transitions if t.event is not None
        )
        clock = interpreter.clock
        self._time_source: Interpreter | None = None
        if type(clock) is SynchronizedClock and type(clock._interpreter).time is Interpreter.time:
            self._time_source = clock._interpreter
        # needs(): per set of active states, (meta-event name, discriminant) -> whether it could
        # react, and the context names those answers read (name -> object)
        self._interests: dict[frozenset[str], _Interest] = {}
        # the interest of the active states, with the configuration set and its version it
        # was found for: (interest, configuration, version)
        self._interest_at: tuple[_Interest, set[str] | None, int] = (_Interest(), None, -1)
        # the evaluator's context, where the names guards read are bound (sismic never
        # replaces it; predicates exist only with a PythonEvaluator, see _static_guards)
        self._context = getattr(interpreter._evaluator, "_context", None)
        # a selected meta-event is consumed without the queue round trip (see
        # FastInterpreter._consume) when the interpreter's class changes none of what it skips
        klass = type(interpreter)
        self._consume_directly = self._can_skip and all(
            getattr(klass, name) is getattr(FastInterpreter, name)
            for name in ("execute_once", "_compute_steps", "queue", "_queue_event",
                         "_select_event", "_select_transitions")
        )
        # an execution's effect can be remembered and replayed (see _effect_of) only when
        # nothing else could happen in it: sismic's own action and entry/exit calls (which do
        # nothing without code), no contracts, no history memory to update
        evaluator = interpreter._evaluator
        self._effects_possible = (
            self._consume_directly
            and type(evaluator).execute_action is Evaluator.execute_action
            and _standard_actions(evaluator)
            and not interpreter._contracts_possible
            and not interpreter._tables.history_children
        )
        self._selection_key: tuple[str, str] | None = None  # of the last remembered selection
        # needs(): the interest found valid during step `_checked_step` of the bound interpreter
        source = self._time_source
        self._step_source = source if isinstance(source, FastInterpreter) else None
        self._checked: _Interest | None = None
        self._checked_step = -1
        # static guards are only as exact as the evaluator is stock
        self._static_guards = (
            self._can_skip
            and self._time_source is not None
            and type(interpreter._evaluator).evaluate_guard in PURE_GUARD_EVALUATIONS
        )

    @property
    def interpreter(self) -> Interpreter:
        """The property statechart's interpreter."""
        return self._interpreter

    def needs(self, name: str, value: Any) -> bool:
        """False when delivering the meta-event ``name`` now would change nothing but the
        property's time: the property is settled, with nothing queued, no time-triggered
        transition active if the time moved, and no transition of an active state listens to
        ``name`` with a guard that could hold. The time is then moved here, as the delivery
        would. ``value`` is the event's discriminant (:mod:`rasm.statechart.meta_guards`), None
        when unknown. True means "deliver it" (the delivery then decides exactly, as always)."""
        interest = self._checked
        checked = False  # whether the checks below ran (and passed) in this call
        moved = None
        if interest is None or self._checked_step != self._step_source._step_count:  # type: ignore
            if not self._settled or not self._static_guards:
                return True
            interp = self._interpreter
            if (
                interp._listeners
                or interp._internal_queue
                or interp._external_queue
                or not interp._configuration
            ):
                return True
            # _current_interest(), its usual answer without the call: the same states as last
            interest, interest_conf, version = self._interest_at
            if not (
                interp._configuration is interest_conf
                and interp._conf_version == version
                and (not interest.watch or self._watch_holds(interest))
            ):
                interest = self._current_interest()
            now = self._time_source._time  # type: ignore[union-attr]
            if interp._time != now:
                if interest.eventless:
                    return True  # the execution evaluates time-triggered transitions anew
                moved = now  # moved below if the answer is no
            checked = True
        found = interest.listening.get(name)
        if found is None:
            found = interest.listening[name] = self._listening(name)
            if name == "step started":
                interest.quiet_start = found is False
        if type(found) is bool:
            decided = found
        else:
            decided = found.get(value)
            if decided is None:
                decided = found[value] = self._decide(name, value, interest)
        if checked:
            if moved is not None:
                if decided:
                    # delivered: queued at the time before, as stock's, and its execution
                    # moves the time
                    return True
                # This meta-event's execution would record the new time and nothing else: that
                # is done here, and the later ones of the step find the time moved.
                interp = self._interpreter
                hook = self.before_time_change or self.before_change
                if hook is not None:
                    hook(interp)
                interp._time = moved
            if self._step_source is not None:
                # Until this step of the bound interpreter ends or this listener feeds its
                # property, nothing checked above can change: only the listener changes the
                # property while the bound interpreter steps.
                self._checked, self._checked_step = interest, self._step_source._step_count
        return decided

    def _current_interest(self) -> _Interest:
        """What is known about the active configuration (the interpreter's, non-empty), valid
        for the context names it read as they are bound now."""
        interp = self._interpreter
        conf = interp._configuration
        interest, interest_conf, version = self._interest_at
        if (
            conf is interest_conf
            and interp._conf_version == version
            and self._watch_holds(interest)
        ):
            return interest
        key = frozenset(conf)
        interest = self._interests.get(key)
        # what was found for these states may read names rebound since (by the property's own
        # actions, or from outside): then nothing remembered is trusted
        if interest is None or not self._watch_holds(interest):
            interest = self._interests[key] = _Interest(not self._eventless_sources.isdisjoint(key))
        self._interest_at = (interest, conf, interp._conf_version)
        return interest

    def _watch_holds(self, interest: _Interest) -> bool:
        # the context names a predicate read must still be bound to the same objects
        watch = interest.watch
        if watch:
            context = self._context
            for name, bound in watch.items():
                if context.get(name, MISSING) is not bound:
                    self._interests.clear()
                    self._interest_at = (self._interest_at[0], None, -1)
                    return False
        return True

    def _transitions_for(self, name: str) -> list[Transition]:
        interp = self._interpreter
        chart = interp.statechart
        return [
            t for state in interp._configuration for t in chart.transitions_from(state)
            if t.event == name
        ]

    def _listening(self, name: str) -> bool | dict[Any, bool]:
        """False: no active transition listens to ``name``; True: one does, whatever the
        discriminant; otherwise a memo (discriminant -> whether a guard could hold)."""
        transitions = self._transitions_for(name)
        if not transitions:
            return False
        if any(t.guard is None for t in transitions) or name not in DISCRIMINANT:
            return True
        return {}

    def _predicates(self, name: str, interest: _Interest) -> list[tuple[Transition, Any]]:
        """The active transitions listening to ``name``, each with its guard's predicate (None
        when undecided, True when there is no guard); the names they read are watched."""
        found = interest.predicates.get(name)
        if found is None:
            context = self._interpreter._evaluator._context
            found = []
            for transition in self._transitions_for(name):
                if transition.guard is None:
                    found.append((transition, True))
                    continue
                decided = guard_predicate(transition.guard, name, context)
                if decided is not None:
                    interest.watch.update(decided[1])
                found.append((transition, None if decided is None else decided[0]))
            interest.predicates[name] = found
        return found

    def _decide(self, name: str, value: Any, interest: _Interest) -> bool:
        if not _decidable(value):
            return True
        for _, predicate in self._predicates(name, interest):
            # None: undecided guard, or one that would raise (the delivery raises it again)
            if predicate is None or predicate is True or predicate(value) is not False:
                return True
        return False

    def _selection(self, event: MetaEvent, now: float) -> list[Transition] | None:
        """For a settled property: what executing ``event`` at ``now`` would select, or None
        when only executing it can tell (something due, time-triggered transitions to evaluate,
        a guard that raises)."""
        interp = self._interpreter
        conf = interp._configuration
        if interp._listeners or not conf or _has_delay(event):
            return None  # (settled implies initialised: no configuration means final)
        internal, external = interp._internal_queue, interp._external_queue
        if (internal and internal[0][0] <= now) or (external and external[0][0] <= now):
            return None
        eventless = not self._eventless_sources.isdisjoint(conf)
        if interp._time != now and eventless:
            return None
        name = event.name
        if name not in self._names or name not in interp.reactive_events():
            return []
        # Without eventless transitions to look at, a selection made only of guards decided by
        # the discriminant depends on nothing else: it is remembered.
        key = self._selection_key = None
        if self._static_guards and not eventless and name in DISCRIMINANT:
            value = _discriminant(event)
            interest = self._current_interest()
            key = (name, value)
            known = interest.selections.get(key)
            if known is not None:
                self._selection_key = key
                return list(known)
            if not _decidable(value) or any(
                p is None for _, p in self._predicates(name, interest)
            ):
                key = None
        before = interp._time
        interp._time = now  # guards see the time the execution would record
        try:
            selected = interp._select_transitions(event, conf)
        except Exception:
            return None
        finally:
            interp._time = before
        if key is not None:
            interest.selections[key] = tuple(selected)
            self._selection_key = key
        return selected

    def _effect_of(self, step: MacroStep) -> tuple | None:
        """What ``step`` (an execution that selected by static guards alone) did, if that is
        all an execution with the same selection will ever do: only states exited and entered
        (no action, no entry or exit code, no history, no contract), nothing sent, left quiet.
        (exited states, sources made idle, entered states) in order; None otherwise."""
        if not self._effects_possible:
            return None
        exited: list[str] = []
        sources: list[str] = []
        entered: list[str] = []
        states = self._interpreter._tables.state
        for micro in step.steps:
            transition = micro.transition
            if micro.sent_events or (transition is not None and transition.action):
                return None
            for name in (*micro.exited_states, *micro.entered_states):
                state = states.get(name)
                if state is None or getattr(state, "on_entry", None) or getattr(
                    state, "on_exit", None
                ):
                    return None
            exited.extend(micro.exited_states)
            if transition is not None:
                sources.append(transition.source)
            entered.extend(micro.entered_states)
        return tuple(exited), tuple(sources), tuple(entered)

    def _quiet(self, interp: FastInterpreter) -> bool:
        # the closing step would also clear what the last step sent (a notify() is sent without
        # being queued): when there is something to clear, it runs
        return not (
            interp._listeners
            or interp._internal_queue
            or interp._external_queue
            or interp._sent_events
            or not self._eventless_sources.isdisjoint(interp._configuration)
        )

    def deliver(self, event: MetaEvent, value: Any) -> tuple | None:
        """Deliver ``event`` (discriminant ``value``), which :meth:`needs` has just let through
        in this step: when what its execution does is remembered for the active states (see
        ``_effect_of``), it is replayed at once. What :meth:`needs` checked before remembering
        its answer for the step (settled, nothing queued, same time, decided guards) is what
        ``__call__`` would check again; the rest is ``__call__``. Returns the effect replayed,
        None when the event was executed."""
        interest = self._checked
        if (
            interest is not None
            and not interest.eventless
            and self._checked_step == self._step_source._step_count  # type: ignore[union-attr]
            and "delay" not in event.data
        ):
            key = (event.name, value)
            effect = interest.effects.get(key)
            if effect is not None:
                interp = self._interpreter
                hook = self.before_state_change or self.before_change
                if hook is not None:
                    hook(interp)
                _replay(interp, effect, self._time_source._time)  # type: ignore[union-attr]
                # needs() would find the same as before the replay, for the states it led to
                target = interest.targets.get(key)
                if target is not None and self._watch_holds(target):
                    self._interest_at = (target, interp._configuration, interp._conf_version)
                else:
                    target = interest.targets[key] = self._current_interest()
                self._checked = target
                return effect
        self(event)
        return None

    def __call__(self, event: MetaEvent) -> None:
        interp = self._interpreter
        self._checked = None  # whatever happens next may change the property
        source = self._step_source
        if source is not None:  # nor is what the bound interpreter's listeners did known
            source._fold.step = -1
        selected = None
        if self._settled:  # only ever true when skipping is possible
            # the bound interpreter's time, without SynchronizedClock's two property calls
            source = self._time_source
            now = interp.clock.time if source is None else source._time
            selected = self._selection(event, now)
            if selected is not None and not selected:
                if interp._time != now:  # what the skipped execution would have recorded
                    hook = self.before_time_change or self.before_change
                    if hook is not None:
                        hook(interp)
                    interp._time = now
                return
        self._settled = False
        self._starter = None
        effect = None
        if selected and self._consume_directly and selected[0].event is not None:
            key, interest = self._selection_key, self._interest_at[0]
            effect = None if key is None else interest.effects.get(key)
        hook = self.before_change if effect is None else (
            self.before_state_change or self.before_change
        )
        if hook is not None:
            hook(interp)
        if selected and self._consume_directly and selected[0].event is not None:
            if effect is not None:
                _replay(interp, effect, now)
            else:
                step = interp._consume(event, selected, now)  # type: ignore[attr-defined]
                quiet = self._quiet(interp)
                if key is not None and quiet and interp._configuration:
                    effect = self._effect_of(step)
                    if effect is not None:
                        interest.effects[key] = effect
                while not quiet and interp.execute_once() is not None:
                    quiet = self._quiet(interp)
        elif self._can_skip:
            interp.queue(event)
            if selected:
                interp._preselected = (event, selected)
            try:
                step = interp.execute_once()
            finally:
                interp._preselected = None
            while step is not None and not self._quiet(interp):
                step = interp.execute_once()
        else:
            interp.queue(event)
            interp.execute()
        if interp.final:
            raise PropertyStatechartError(self._interpreter)
        self._settled = self._can_skip
        self._starter = self._step_source if self._settled and self._static_guards else None
