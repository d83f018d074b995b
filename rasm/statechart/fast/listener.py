"""Feeding a property statechart only the meta-events it can react to.

Stock sismic executes a bound property statechart for every meta-event of every step (some twenty
per step of a small chart), although most find no transition to take: the execution then consumes
the event in an empty step and records the time, nothing else. :class:`PropertyListener` decides
that without the execution, from the names of the events the active states listen to and, for
guards that compare the meta-event's state or event name with constants, from that name alone
(:mod:`rasm.statechart.fast.meta_guards`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sismic.interpreter import Interpreter
from sismic.interpreter.listener import PropertyStatechartListener
from sismic.model import Transition

from rasm.statechart.fast.meta_guards import MISSING, NO_EVENT, Predicate, guard_predicate

__all__ = ["PropertyListener"]


def _decidable(value: Any) -> bool:
    """Whether guard predicates can decide for this discriminant (None: unknown)."""
    return isinstance(value, str) or value is NO_EVENT


class PropertyListener(PropertyStatechartListener):
    """Feeds meta-events to a property statechart, skipping the executions that would do nothing.

    When the property interpreter is *settled* (its last execution completed, nothing is queued,
    no listener of its own, no invariant among its active states), an execution for a meta-event
    can only do something if

    - a transition of an active state listens to the meta-event's name and its guard may hold
      (a guard that :func:`~rasm.statechart.fast.meta_guards.guard_predicate` cannot decide from
      the meta-event's discriminant may hold), or
    - the time moved since the last execution and an active state has an eventless transition
      (``after``, ``idle``, time guards), which the execution would evaluate anew.

    Otherwise :meth:`skip` does what the execution would have done: record the time.

    Skipping needs a property interpreter whose selection can be asked
    (:class:`~rasm.statechart.fast.FastInterpreter`) and whose guards are Python expressions
    (sismic's ``PythonEvaluator`` or a subclass that keeps its guard semantics); the binding
    interpreter says so with ``skips``. Guards are assumed free of side effects, and guards of
    eventless transitions to depend only on the property's own context, configuration and time.
    """

    #: Called with the property's interpreter just before the listener executes it; the
    #: platform's atomic layer snapshots the property there.
    before_change: Callable[[Interpreter], Any] | None = None
    #: Called instead of :attr:`before_change` when the listener only moves the property's time
    #: (a skipped meta-event at a new time); the atomic layer then saves just the time.
    before_time_change: Callable[[Interpreter], Any] | None = None

    def __init__(self, interpreter: Interpreter, *, skips: bool = False) -> None:
        super().__init__(interpreter)
        self._skips = skips
        self._settled = False
        # guard predicates by (transition, meta-event name), with the context names they read
        self._predicates: dict[tuple[int, str], tuple[Predicate | None, dict[str, Any]]] = {}

    @property
    def interpreter(self) -> Interpreter:
        """The property statechart's interpreter."""
        return self._interpreter

    def wants(self, name: str, value: Any) -> bool:
        """Whether delivering the meta-event ``name`` (discriminant ``value``, None when unknown)
        now could change more than the property's time. True means "deliver it": the delivery
        then decides exactly, as always."""
        if not self._settled:
            return True
        interp: Any = self._interpreter
        if interp._listeners or interp._internal_queue or interp._external_queue:
            return True
        if interp._time != interp.clock.time and interp.listening(None):
            return True  # the execution evaluates time-triggered transitions anew
        for transition in interp.listening(name):
            if transition.guard is None or not _decidable(value):
                return True
            predicate = self._predicate(transition, name)
            # None: undecided guard, or one that would raise (the delivery raises it again)
            if predicate is None or predicate(value) is not False:
                return True
        return False

    def skip(self) -> None:
        """What delivering a meta-event that :meth:`wants` refused would do: record the time."""
        interp = self._interpreter
        now = interp.clock.time
        if interp._time != now:
            hook = self.before_time_change or self.before_change
            if hook is not None:
                hook(interp)
            interp._time = now

    def __call__(self, event: Any) -> None:
        if self.before_change is not None:
            self.before_change(self._interpreter)
        self._settled = False
        super().__call__(event)
        self._settled = self._skips and not self._invariants_active()

    def _invariants_active(self) -> bool:
        # invariants see every consumed event: a property with active ones is always executed
        interp: Any = self._interpreter
        return any(
            getattr(interp._state(name), "invariants", None) for name in interp._configuration
        )

    def _predicate(self, transition: Transition, name: str) -> Predicate | None:
        """The guard's predicate over the discriminant of ``name`` (None: undecided), valid while
        the context names it read are bound to the same objects."""
        context = self._interpreter.context
        found = self._predicates.get((id(transition), name))
        if found is None or any(context.get(k, MISSING) is not v for k, v in found[1].items()):
            decided = guard_predicate(transition.guard, name, context)  # type: ignore[arg-type]
            found = (None, {}) if decided is None else decided
            self._predicates[(id(transition), name)] = found
        return found[0]
