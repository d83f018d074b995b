"""Executing a chart: sismic's semantics, with atomic steps and a known next deadline.

Two things stock sismic lacks and the platform needs:

* **Atomic steps.** An exception inside a step (an action, a guard, a contract, a property
  statechart) leaves sismic half-applied: old state exited, new one not entered, event consumed.
  :class:`AtomicStepMixin` saves the interpreter's mutable state before a step changes it (lazily:
  most steps change nothing) and restores it when the step raises, records the exception in
  :attr:`last_failure` and raises :class:`~rasm.errors.ExecutionError` from it (its ``cause``:
  sismic's ``ContractError``, ``PropertyStatechartError``, ``CodeEvaluationError``, …). The
  event that caused the failure is discarded, so the next step does not fail on it again.
  Meta-events for ordinary listeners (``bind``, ``attach``) are delivered only when the step
  succeeds, so a bound interpreter never receives an event sent by a step that was rolled back.
* **The next deadline.** ``after()``/``idle()`` guards and delayed events are only looked at when a
  step runs, and sismic offers no "when should I run next". :meth:`Interpreter.next_deadline`
  answers it, so a live runner sleeps until then (or until an event arrives) instead of polling.
  Timers are exact (:mod:`rasm.statechart.timers`): a step run at that deadline finds the timer
  holding, whatever the time the state was entered.
"""

from __future__ import annotations

import copy
import functools
import math
from dataclasses import dataclass
from types import CodeType
from typing import Any

from sismic.exceptions import CodeEvaluationError, ContractError
from sismic.interpreter import Interpreter as SismicInterpreter
from sismic.interpreter.listener import PropertyStatechartListener
from sismic.model import Event, InternalEvent, MetaEvent

from rasm.errors import ExecutionError, RasmError, is_interrupt
from rasm.statechart.fast import FastInterpreter
from rasm.statechart.timers import ExactTimerEvaluator, deadline, elapsed

__all__ = [
    "AtomicStepMixin", "DeadlineEvaluator", "FastGuardEvaluator", "Interpreter", "StepFailure",
]

_IMMUTABLE = (int, float, complex, str, bytes, bool, type(None), frozenset)
_LATER = object()  # a snapshot's context, to be saved before the step's first code runs


def _copy_value(value: Any) -> Any:
    if isinstance(value, _IMMUTABLE):
        return value
    if isinstance(value, tuple) and all(isinstance(v, _IMMUTABLE) for v in value):
        return value
    try:
        return copy.deepcopy(value)
    except Exception:  # modules, locks, …: cannot be copied; rebinding is still restored
        return value


def _consumed_from(light: tuple, internal: list, external: list) -> list | None:
    """Which of the queues saved before a failed step (``light``) had the event the step
    consumed at its head: a step consumes at most one event, the head of one queue, and
    otherwise only adds events."""
    for before, after in ((light[3], internal), (light[4], external)):
        if before:
            head = before[0][1]
            if not any(event is head for _, event in after):
                return before
    return None


@dataclass(frozen=True)
class StepFailure:
    """What went wrong in the last failed step: the event it was processing and the exception."""

    time: float
    event: Event | None
    exception: BaseException


def _waited(since: float, now: float, seconds: float, deadlines: list | None) -> bool:
    """``after``/``idle``: true once ``seconds`` have passed since ``since`` (exactly,
    :mod:`rasm.statechart.timers`); otherwise ``(since, seconds)`` is recorded in
    ``deadlines`` (if any), for :meth:`Interpreter.next_deadline` to add up when asked."""
    if elapsed(since, now, seconds):
        return True
    if deadlines is not None:
        deadlines.append((since, seconds))
    return False


# Names through which a guard could see the whole dict of names exposed to it: a guard using one
# gets all of them, as with stock sismic.
_INTROSPECTION = frozenset({
    "globals", "locals", "vars", "dir", "eval", "exec", "__builtins__", "__globals__",
    "f_globals", "f_locals", "f_back", "_getframe", "gi_frame", "cr_frame", "ag_frame", "tb_frame",
})
_EXPOSED = frozenset({"active", "time", "after", "idle", "event"})
_ACTION_EXPOSED = frozenset({"active", "time", "send", "notify", "setdefault"})
_EVENT_ONLY = frozenset({"event"})
_NOTHING, _EVENT, _ALL = 0, 1, 2  # which of _EXPOSED a guard gets


def _names_used(code: CodeType) -> frozenset[str]:
    """Every name a code object (and the lambdas, comprehensions inside it) may look up."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, CodeType):
            names |= _names_used(const)
    return frozenset(names)


def _escaped(exc: BaseException, doing: str) -> CodeEvaluationError:
    """What chart code raised that is not an ``Exception`` (``sys.exit()``, ``raise
    KeyboardInterrupt``) as a failure of the step like any other, so it is rolled back and
    reported. (A real interrupt is re-raised as is by the caller: it stops the run.)"""
    what = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    return CodeEvaluationError(f"'{what}' occurred while {doing}")


class FastGuardEvaluator(ExactTimerEvaluator):
    """sismic's Python evaluator with guards evaluated in one frame instead of two (guards run at
    every step), exposing only the names a guard uses: the same values, the same errors; its
    timers are exact (:class:`~rasm.statechart.timers.ExactTimerEvaluator`)."""

    deadlines: list | None = None  # where DeadlineEvaluator records its timers: (since, seconds)
    #: The event a guard raised on (sismic looks at an event before it takes it from the queue).
    failed_event: Any = None
    #: Called before any action, entry or exit code runs (the atomic layer saves the context
    #: there, once per step: a step that runs no code cannot change it).
    before_code: Any = None

    def __init__(self, interpreter=None, *, initial_context=None) -> None:
        super().__init__(interpreter, initial_context=initial_context)
        # guard -> (code, names kind, the exposed names it uses)
        self._guard_codes: dict[str, tuple[CodeType, int, frozenset[str]]] = {}
        # action code -> (compiled, the exposed names it uses)
        self._action_codes: dict[str, tuple[CodeType, frozenset[str]]] = {}

    def _compile_guard(self, guard: str) -> tuple[CodeType, int, frozenset[str]]:
        code = self._evaluable_code.get(guard)
        if code is None:
            code = self._evaluable_code.setdefault(guard, compile(guard, "<string>", "eval"))
        names = _names_used(code)
        wanted = _EXPOSED if names & _INTROSPECTION else names & _EXPOSED
        kind = _ALL if wanted - _EVENT_ONLY else _EVENT if wanted else _NOTHING
        found = self._guard_codes[guard] = (code, kind, wanted)
        return found

    def evaluate_guard(self, transition, event=None) -> bool:
        guard = getattr(transition, "guard", None)
        if guard is None:
            return True
        found = self._guard_codes.get(guard)
        code, kind, wanted = self._compile_guard(guard) if found is None else found
        if kind == _EVENT:  # the usual guard of a property statechart
            exposed: dict[str, Any] = {"event": event}
        elif kind == _NOTHING:
            exposed = {}
        else:  # what it uses of active, time, after, idle, event (a timer: `after` alone)
            interp = self._interpreter
            source = transition.source
            now = interp.time
            deadlines = self.deadlines
            exposed = {}
            if "active" in wanted:
                exposed["active"] = lambda s: s in interp.configuration
            if "time" in wanted:
                exposed["time"] = now
            if "after" in wanted:
                exposed["after"] = lambda s: _waited(interp._entry_time[source], now, s, deadlines)
            if "idle" in wanted:
                exposed["idle"] = lambda s: _waited(interp._idle_time[source], now, s, deadlines)
            if "event" in wanted:
                exposed["event"] = event
        try:
            return bool(eval(code, exposed, self._context))
        except Exception as e:
            self.failed_event = event
            raise CodeEvaluationError(f"'{e}' occurred while evaluating '{guard}'") from e
        except BaseException as e:
            if is_interrupt(e):
                raise
            self.failed_event = event
            raise _escaped(e, f"evaluating '{guard}'") from e

    def _evaluate_code(self, code, *, additional_context=None):
        """sismic's (contract conditions), with :func:`_escaped` for what is not an Exception."""
        try:
            return super()._evaluate_code(code, additional_context=additional_context)
        except Exception:
            raise
        except BaseException as e:
            if is_interrupt(e):
                raise
            raise _escaped(e, f"evaluating '{code}'") from e

    def _execute_code(self, code, *, additional_context=None):
        """sismic's ``_execute_code`` (actions, entry and exit code, the preamble), exposing only
        the names the code uses (all of them when it could look at its namespace): building
        ``send``, ``notify`` and ``active`` for code that never calls them is most of the cost
        of a one-line action."""
        if code is None:
            return []
        found = self._action_codes.get(code)
        if found is None:
            compiled = self._executable_code.get(code)
            if compiled is None:
                compiled = self._executable_code.setdefault(code, compile(code, "<string>", "exec"))
            names = _names_used(compiled)
            found = self._action_codes[code] = (
                compiled, _ACTION_EXPOSED if names & _INTROSPECTION else names & _ACTION_EXPOSED
            )
        compiled, wanted = found
        if self.before_code is not None:
            self.before_code()
        sent_events: list[Event] = []
        exposed: dict[str, Any] = {}
        if wanted:
            interp = self._interpreter
            if "active" in wanted:
                exposed["active"] = lambda name: name in interp.configuration
            if "time" in wanted:
                exposed["time"] = interp.time
            if "send" in wanted:
                exposed["send"] = lambda name, **kw: sent_events.append(InternalEvent(name, **kw))
            if "notify" in wanted:
                exposed["notify"] = lambda name, **kw: sent_events.append(MetaEvent(name, **kw))
            if "setdefault" in wanted:
                exposed["setdefault"] = self._setdefault
        if additional_context:
            exposed.update(additional_context)
        try:
            exec(compiled, exposed, self._context)  # noqa: S102 - the chart's own code
            return sent_events
        except Exception as e:
            raise CodeEvaluationError(f"'{e}' occurred while executing '{code}'") from e
        except BaseException as e:
            if is_interrupt(e):
                raise
            raise _escaped(e, f"executing '{code}'") from e


class DeadlineEvaluator(FastGuardEvaluator):
    """:class:`FastGuardEvaluator` that also records when ``after()``/``idle()`` guards turn true.

    A guard is evaluated at every step while its source state is active, so the deadlines recorded
    during the last step are exactly those that can fire a transition without a new event.
    """

    def __init__(self, interpreter=None, *, initial_context=None) -> None:
        super().__init__(interpreter, initial_context=initial_context)
        self.deadlines = []


class AtomicStepMixin:
    """Makes ``execute_once`` all-or-nothing; see the module docstring."""

    last_failure: StepFailure | None = None
    #: Whether the evaluator calls :meth:`_save_context` before it runs code (its before_code).
    _code_announced = False

    def _property_interpreters(self) -> list[Any]:
        return [
            listener._interpreter
            for listener in self._listeners
            if isinstance(listener, PropertyStatechartListener)
        ]

    def _snapshot(self, with_properties: bool = True) -> tuple:
        # Everything at once: for a property statechart before its first change in a step, or
        # up front when a bound property's listener cannot say when it changes it.
        state = (
            self._initialized, self._time, self._sent_events.copy(),
            self._internal_queue.copy(), self._external_queue.copy(),
        )
        props = (
            tuple((p, AtomicStepMixin._snapshot(p)) for p in self._property_interpreters())
            if with_properties and self._listeners else ()
        )
        return state, AtomicStepMixin._state_snapshot(self), props

    def _state_snapshot(self, context_later: bool = False) -> list:
        """What a micro step may change besides the time and the queues (which execute_once
        saves before the step starts): configuration, entry and idle times, and where the chart
        can change them (None where it cannot), history memory, context and contract memory.
        With ``context_later``, the context is left to :meth:`_save_context` (``_LATER``) when
        the evaluator calls it before running any code. Also used on bound property
        interpreters, which may be stock sismic's."""
        evaluator = self._evaluator
        context = (
            _LATER
            if context_later and self._code_announced
            else AtomicStepMixin._context_copy(self)
        )
        # a fast interpreter's tables say whether the chart has history states or contracts
        tables = getattr(self, "_tables", None)
        return [
            self._memory.copy() if tables is None or tables.history_children else None,
            self._configuration.copy(), self._entry_time.copy(), self._idle_time.copy(), context,
            dict(getattr(evaluator, "_memory", {})) if tables is None or tables.contracts else None,
        ]

    def _context_copy(self) -> dict:
        return {key: _copy_value(value) for key, value in self._evaluator._context.items()}

    def _save_context(self) -> None:
        # FastGuardEvaluator.before_code: the first code of a step is about to run
        saved = self._lazy_snapshot
        if saved and saved[4] is _LATER:
            saved[4] = self._context_copy()

    def _restore(self, snapshot: tuple) -> None:
        state, inner, props = snapshot
        (self._initialized, self._time, self._sent_events, self._internal_queue,
         self._external_queue) = state
        AtomicStepMixin._restore_state(self, inner)
        for interp, snap in props:
            AtomicStepMixin._restore(interp, snap)

    def _restore_state(self, inner: list) -> None:
        memory, self._configuration, self._entry_time, self._idle_time, context, evaluated = inner
        if memory is not None:
            self._memory = memory
        if context is not _LATER:  # _LATER: no code ran
            self._evaluator._context.clear()
            self._evaluator._context.update(context)
        if evaluated is not None and hasattr(self._evaluator, "_memory"):
            self._evaluator._memory = evaluated

    def _apply_step(self, step):
        # This interpreter's full snapshot is taken here, before the step's first change: most
        # steps find nothing to do and never get this far.
        if self._lazy_snapshot is None:
            self._lazy_snapshot = self._state_snapshot(context_later=True)
        return super()._apply_step(step)

    _lazy_snapshot: list | tuple | None = ()  # () = not in a lazily snapshotted step
    # What bound property interpreters looked like before their first change in this step, by
    # id: (full snapshots, times before a skipped meta-event); each property is in at most one of
    # them, the broadest taken. Set only in steps of an interpreter with property listeners.
    _property_records: tuple[dict, dict] | None = None

    def _before_property_change(self, interp: Any) -> None:
        # Called by a bound PropertyListener before it feeds its interpreter a meta-event; most
        # meta-events are skipped, so most steps snapshot no property at all.
        records = self._property_records
        if records is not None and id(interp) not in records[0]:
            records[0][id(interp)] = (interp, AtomicStepMixin._snapshot(interp))

    def _before_property_time_change(self, interp: Any) -> None:
        # A skipped meta-event only moves the property's time: that is all there is to save
        # (restored after any record taken later in the step, which saw the new time).
        records = self._property_records
        key = id(interp)
        if records is not None:
            full, times = records
            if key not in full and key not in times:
                times[key] = (interp, interp._time)

    def _split_listeners(self, listeners: list) -> tuple[list, list, bool]:
        """Property listeners, ordinary ones, and whether a property must be snapshotted up
        front (its listener does not say when it changes its interpreter, as stock's)."""
        properties = [li for li in listeners if isinstance(li, PropertyStatechartListener)]
        ordinary = [li for li in listeners if not isinstance(li, PropertyStatechartListener)]
        eager = any(getattr(li, "before_change", None) is None for li in properties)
        return properties, ordinary, eager

    def execute_once(self):
        deadlines = getattr(self._evaluator, "deadlines", None)
        if deadlines is not None:  # a DeadlineEvaluator: only this step's timers count
            deadlines.clear()
        if getattr(self._evaluator, "failed_event", None) is not None:
            self._evaluator.failed_event = None
        listeners = self._listeners
        eager = False
        if listeners:
            properties, ordinary, eager = self._split_listeners(listeners)
        else:
            properties = ordinary = ()
        # Before the first micro step only these change (guards are side-effect free): the
        # time, the sent events, and the queues by at most the one event the step consumes. The
        # rest is saved in _apply_step, bound properties in _before_property_change.
        light = (self._initialized, self._time, self._sent_events.copy(),
                 self._internal_queue.copy(), self._external_queue.copy())
        if eager:
            inner = self._state_snapshot()
            saved = tuple((p, AtomicStepMixin._snapshot(p)) for p in self._property_interpreters())
        else:
            self._lazy_snapshot = None
            if properties:
                self._property_records = ({}, {})
        deferred: list[Any] = []
        if ordinary:
            # Hold meta-events for ordinary listeners until the step has succeeded.
            self._listeners = [*properties, deferred.append]
        try:
            step = super().execute_once()
        except Exception as exc:
            self._listeners = listeners
            if isinstance(exc, ContractError) and exc.context is not None:
                # sismic's error holds the live context: keep what it was at the failure, which
                # the rollback below is about to undo
                exc._context = dict(exc.context)
            consumed = _consumed_from(light, self._internal_queue, self._external_queue)
            guilty = getattr(self._evaluator, "failed_event", None)
            if consumed is None and guilty is not None:
                # a guard raised on the event at the head of a queue, before the step took it
                consumed = next((q for q in light[3:5] if q and q[0][1] is guilty), None)
            if eager:
                AtomicStepMixin._restore_state(self, inner)
                for interp, snap in saved:
                    AtomicStepMixin._restore(interp, snap)
            else:
                if self._lazy_snapshot:
                    self._restore_state(self._lazy_snapshot)
                # newest first: each older record then puts back what it covers
                snapshots, times = self._property_records or ({}, {})
                for interp, snap in snapshots.values():
                    AtomicStepMixin._restore(interp, snap)
                for interp, before in times.values():
                    interp._time = before
            (self._initialized, self._time, self._sent_events, self._internal_queue,
             self._external_queue) = light
            self._lazy_snapshot = ()
            if self._property_records is not None:
                self._property_records = None
            # Discard the event that made the step fail, or the next step fails on it again.
            event = None if consumed is None else consumed.pop(0)[1]
            self.last_failure = StepFailure(self.time, event, exc)
            if isinstance(exc, RasmError):  # rasm's own (a chart edited under the interpreter)
                raise
            raise ExecutionError(exc) from exc
        self._lazy_snapshot = ()
        if self._property_records is not None:
            self._property_records = None
        if ordinary:
            self._listeners = listeners
            for meta_event in deferred:
                for listener in ordinary:
                    listener(meta_event)
        return step

    def bind_property_statechart(self, statechart, *, interpreter_klass=None):
        # Property statecharts run on the fast path without a rollback layer of their own: this
        # interpreter's snapshot covers them, and restores them when one of its steps fails.
        if interpreter_klass is None:
            interpreter_klass = functools.partial(
                FastInterpreter, evaluator_klass=FastGuardEvaluator
            )
        listener = super().bind_property_statechart(statechart, interpreter_klass=interpreter_klass)
        if hasattr(listener, "before_change"):
            listener.before_change = self._before_property_change
        if hasattr(listener, "before_time_change"):
            listener.before_time_change = self._before_property_time_change
        return listener


class Interpreter(AtomicStepMixin, FastInterpreter):
    """The platform's interpreter: sismic's semantics, faster, with atomic steps and deadlines.

    Same constructor and API as ``sismic.interpreter.Interpreter``; the evaluator defaults to
    :class:`DeadlineEvaluator` so that :meth:`next_deadline` knows the timers.
    """

    def __init__(
        self,
        statechart,
        *,
        evaluator_klass=DeadlineEvaluator,
        initial_context=None,
        clock=None,
        ignore_contract: bool = False,
    ) -> None:
        super().__init__(
            statechart,
            evaluator_klass=evaluator_klass,
            initial_context=initial_context,
            clock=clock,
            ignore_contract=ignore_contract,
        )
        evaluator = self._evaluator
        if type(evaluator)._execute_code is FastGuardEvaluator._execute_code:
            # the context is saved when a step first runs code, not at its first micro step
            evaluator.before_code = self._save_context
            self._code_announced = True

    def next_deadline(self) -> float | None:
        """The earliest time at which a step could do something without a new external event.

        ``None`` means never (only an event can wake the chart); a time not after ``self.time``
        means a step is due now. Valid after :meth:`execute` returned (the last step evaluated the
        timed guards of the current configuration).
        """
        if not self._initialized:
            return self.time
        internal, external = self._internal_queue, self._external_queue
        deadlines = getattr(self._evaluator, "deadlines", ())
        if not (internal or external or deadlines):
            return None  # the usual answer, after every send: nothing queued, no timer
        candidates = [queue[0][0] for queue in (internal, external) if queue]
        candidates.extend(deadline(since, seconds) for since, seconds in deadlines)
        due = min(candidates, default=math.inf)
        return None if due == math.inf else due


assert issubclass(Interpreter, SismicInterpreter)
