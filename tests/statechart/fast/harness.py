"""Run a chart on an interpreter class and record everything observable, step by step.

The same script run on stock sismic and on :class:`FastInterpreter` must give equal records: each
macro step (time, event, and per micro step the transition, entered/exited states and sent
events), then the configuration, context, history memory, entry/idle times, queues and sent events;
an exception is recorded as (type, message) and the run goes on, as a user could. A bound property
statechart's own state is recorded too.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import Any

from sismic.exceptions import NonDeterminismError
from sismic.interpreter import Interpreter
from sismic.model import MacroStep, Statechart

MAX_STEPS = 10  # macro steps per input: eventless or send() loops are legal and never end
MAX_STABILIZATIONS = 200


def bounded(klass: type[Interpreter]) -> type[Interpreter]:
    """``klass`` whose stabilisation gives up after MAX_STABILIZATIONS micro steps per macro step.

    Stock sismic can stabilise forever (a history state recorded in its own memory after an
    exception left a step half-applied); both interpreters get the same bound, so they still
    have to agree on when it is hit.
    """

    class Bounded(klass):  # type: ignore[valid-type,misc]
        def execute_once(self):  # noqa: D102
            self._stabilizations = 0
            return super().execute_once()

        def _create_stabilization_step(self, names):  # noqa: D102
            self._stabilizations += 1
            if self._stabilizations > MAX_STABILIZATIONS:
                raise RuntimeError("stabilisation does not terminate")
            return super()._create_stabilization_step(names)

    return Bounded


def _transition_id(chart: Statechart, transition: Any) -> int | None:
    if transition is None:
        return None
    for i, t in enumerate(chart._transitions):
        if t is transition:
            return i
    raise AssertionError(f"{transition!r} is not a transition of the chart")


def describe_step(chart: Statechart, step: MacroStep | None) -> Any:
    """A comparable description of a macro step (transitions by identity in the chart)."""
    if step is None:
        return None
    return (
        step.time,
        repr(step.event),
        [
            (
                repr(micro.event),
                _transition_id(chart, micro.transition),
                list(micro.entered_states),
                list(micro.exited_states),
                [repr(e) for e in micro.sent_events],
            )
            for micro in step.steps
        ],
    )


def describe_state(interp: Interpreter) -> Any:
    """Everything about an interpreter's run-time state that stock sismic exposes."""
    return {
        "time": interp.time,
        "configuration": interp.configuration,
        "raw_configuration": sorted(interp._configuration),
        "final": interp.final,
        "context": repr(sorted(interp.context.items())),
        "memory": {k: v if v is None else list(v) for k, v in interp._memory.items()},
        "entry": dict(interp._entry_time),
        "idle": dict(interp._idle_time),
        "internal": [(t, repr(e)) for t, e in interp._internal_queue],
        "external": [(t, repr(e)) for t, e in interp._external_queue],
        "sent": [repr(e) for e in interp._sent_events],
    }


def _property(interp: Interpreter) -> Interpreter | None:
    found = _properties(interp)
    return found[0] if found else None


def _properties(interp: Interpreter) -> list[Interpreter]:
    """The interpreters of the property statecharts bound to ``interp``, in binding order."""
    return [
        inner for listener in interp._listeners
        if (inner := getattr(listener, "_interpreter", None)) is not None
    ]


def _error(chart: Statechart, e: Exception) -> tuple[str, ...]:
    """How a failed step is recorded: its error's type and message, but for the one departure
    from stock: two enabled transitions of the root are a non-deterministic choice for rasm,
    where stock fails looking for the root's parent."""
    stock_root = (type(e).__name__, str(e)) == ("StatechartError", "State None does not exist")
    root = f"{chart.root} -> "
    ours_root = isinstance(e, NonDeterminismError) and str(e).startswith(
        f"Non-determinist choice between transitions {root}") and f" and {root}" in str(e)
    if stock_root or ours_root:
        return ("error", "two enabled transitions of the root")
    return ("error", type(e).__name__, str(e))


def run(
    klass: Callable[..., Interpreter],
    chart: Statechart,
    script: Sequence[tuple[float, str, dict]],
    *,
    prop: Statechart | Sequence[Statechart] | None = None,
    ignore_contract: bool = False,
    restore_every: int = 0,
    record_meta: bool = False,
) -> list[Any]:
    """Record a run of ``chart`` on ``klass`` fed with ``script`` (see module docstring).

    ``record_meta`` attaches a listener that records every meta-event, in order.
    ``restore_every`` > 0 snapshots the state attributes before every step and, every that many
    steps, restores them by reassigning copies (what the platform's atomic-step layer does).
    """
    records: list[Any] = []
    try:
        interp = bounded(klass)(chart, ignore_contract=ignore_contract)
        props = [] if prop is None else [prop] if isinstance(prop, Statechart) else list(prop)
        for one in props:
            interp.bind_property_statechart(one, interpreter_klass=klass)
    except Exception as e:  # noqa: BLE001 - the error itself is what is compared
        return [("init error", type(e).__name__, str(e))]
    if record_meta:
        interp.attach(lambda meta: records.append(("meta", repr(meta))))
    counter = 0

    def steps() -> None:
        nonlocal counter
        for _ in range(MAX_STEPS):
            snapshot = _snapshot(interp) if restore_every else None
            try:
                step = interp.execute_once()
            except Exception as e:  # noqa: BLE001
                records.append(_error(chart, e))
                step = None
            else:
                records.append(("step", describe_step(chart, step)))
            counter += 1
            if snapshot is not None and counter % restore_every == 0:
                _restore(interp, snapshot)
                records.append(("restored",))
            records.append(("state", describe_state(interp)))
            for inner in _properties(interp):
                records.append(("property", describe_state(inner)))
            if step is None:
                return

    steps()
    for dt, name, data in script:
        interp.clock.time += dt
        interp.queue(name, **data)
        steps()
    return records


_ATTRIBUTES = (
    "_initialized",
    "_time",
    "_memory",
    "_configuration",
    "_entry_time",
    "_idle_time",
    "_sent_events",
    "_internal_queue",
    "_external_queue",
)


def _snapshot(interp: Interpreter) -> tuple:
    return (
        {name: copy.copy(getattr(interp, name)) for name in _ATTRIBUTES},
        copy.deepcopy(dict(interp._evaluator._context)),
    )


def _restore(interp: Interpreter, snapshot: tuple) -> None:
    attributes, context = snapshot
    for name, value in attributes.items():
        setattr(interp, name, copy.copy(value))
    interp._evaluator._context.clear()
    interp._evaluator._context.update(context)
