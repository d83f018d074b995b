"""``rasm simulate``: run one chart on a simulated clock over a timed list of events.

The steps are exactly those stock sismic's ``Interpreter`` takes when driven the ordinary way:
``execute()`` at time 0 (the initial step, then any eventless steps), then for each event in turn
the clock is set to the event's time, the event is queued and ``execute()`` runs until the chart is
stable. A line without an event only moves the clock: the chart then runs until it is stable,
so the timers due by then fire. ``until`` optionally advances the clock once more at the end.

Times are exact (:mod:`rasm.statechart.timers`): a timer fires at its deadline, where stock
sismic's binary arithmetic can miss it (entered at 7.7, ``after(2)`` holds at 9.7), and the output
gives each time as the decimal it was written as.

An event may carry ``context``: variables set in the chart's context just before it is queued,
as the platform sets a stage chart's ``knowledge``, ``time`` and ``anomaly`` before each of its
stage's events; so a stage chart can be simulated on its own.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from keyword import iskeyword
from pathlib import Path
from typing import Any, TextIO

from sismic.clock import SimulatedClock
from sismic.model import MacroStep, Statechart

from rasm.errors import ExecutionError, Location, SourceError, SourceErrors, not_utf8
from rasm.statechart.interpreter import Interpreter
from rasm.statechart.load import load_statechart, source_of
from rasm.times import format_seconds

__all__ = ["TimedEvent", "SimulatedStep", "read_events", "simulate", "format_steps"]

# keyword names of sismic's Event and Interpreter.queue: an event's data cannot use them
MAX_STEPS = 10_000  # macro steps one event (or the initial step) may take before it is stable
_RESERVED = {"name", "data", "delay", "self", "event_or_name"}


@dataclass(frozen=True)
class TimedEvent:
    """One line of an events file: ``{"time": t, "event": "name", "data": {...}}``, and
    optionally ``"context": {...}``, variables set in the chart's context before the event.
    A line without ``event`` (``name`` None) only moves the clock to ``time``."""

    time: float
    name: str | None
    data: dict[str, Any] = field(default_factory=dict)
    line: int = 0
    context: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SimulatedStep:
    """One macro step as ``rasm simulate`` reports it."""

    time: float
    event: str | None
    configuration: list[str]
    entered: list[str]
    exited: list[str]
    error: str | None = None
    sent: list[tuple[str, dict[str, Any]]] = field(default_factory=list)  # send()'s events

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "time": self.time,
            "event": self.event,
            "configuration": self.configuration,
            "entered": self.entered,
            "exited": self.exited,
        }
        if self.error is not None:
            out["error"] = self.error
        return out


def _parse_events(lines: Iterable[str], file: str) -> list[TimedEvent]:
    events: list[TimedEvent] = []
    errors: list[SourceError] = []
    last_time = -math.inf
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue

        def bad(message: str, col: int = 1, number: int = number) -> None:
            errors.append(SourceError(message, Location(file, number, col)))

        try:
            record = json.loads(text, parse_int=_bounded_int)
        except json.JSONDecodeError as exc:
            bad(f"not JSON: {exc.msg}", exc.colno)
            continue
        except ValueError as exc:  # _bounded_int
            bad(str(exc))
            continue
        except RecursionError:
            bad(f"nested too deeply (more than about {sys.getrecursionlimit()} levels)")
            continue
        if not isinstance(record, dict):
            bad('an event is a JSON object {"time": t, "event": "name", "data": {...}}')
            continue
        unknown = sorted(set(record) - {"time", "event", "data", "context"})
        if unknown:
            bad(f"unknown key {unknown[0]!r} (expected time, event, data, context)")
            continue
        time = record.get("time")
        if isinstance(time, bool) or not isinstance(time, int | float) or not _finite(time):
            bad('"time" must be a finite number of seconds')
            continue
        if time < 0:
            bad(f"time {format_seconds(time)} is negative")
            continue
        if time < last_time:
            bad(f"time {format_seconds(time)} goes back (the previous event is at "
                f"{format_seconds(last_time)})")
            continue
        name = record.get("event")
        if name is None and "event" not in record:
            given = sorted({"data", "context"} & set(record))
            if given:
                bad(f'"{given[0]}" belongs to an event: add "event", or leave "{given[0]}" out '
                    "to only move the clock")
                continue
            last_time = time
            events.append(TimedEvent(time, None, line=number))
            continue
        if not isinstance(name, str) or not name:
            bad('"event" must be a non-empty string')
            continue
        data = record.get("data", {})
        if not isinstance(data, dict):
            bad('"data" must be a JSON object')
            continue
        reserved = sorted(_RESERVED & set(data))
        if reserved:
            bad(f"data key {reserved[0]!r} is reserved by sismic; rename it")
            continue
        context = record.get("context", {})
        if not isinstance(context, dict):
            bad('"context" must be a JSON object of variable names and values')
            continue
        names = [key for key in context if not key.isidentifier() or iskeyword(key)]
        if names:
            bad(f"context key {names[0]!r} is not a variable name the chart's code could read")
            continue
        last_time = time
        events.append(TimedEvent(time, name, data, number, context))
    if errors:
        raise SourceErrors(errors)
    return events


def _bounded_int(text: str) -> int:
    # int() of a text past 4300 digits is refused by Python: say so in the user's terms
    digits = len(text.lstrip("-"))
    if digits > 4300:
        raise ValueError(f"integer with {digits} digits is too long (at most 4300)")
    return int(text)


def _finite(time: float) -> bool:
    try:
        return math.isfinite(time)
    except OverflowError:  # an integer too large for a float
        return False


def read_events(source: str | Path | TextIO) -> list[TimedEvent]:
    """Read a JSONL events file (a path, ``-`` for standard input, or an open text stream)."""
    if isinstance(source, str) and source == "-":
        source = sys.stdin
    if isinstance(source, str | Path):
        try:
            text = Path(source).read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise not_utf8(str(source), exc) from None
        return _parse_events(text.split("\n"), str(source))
    name = "<stdin>" if source is sys.stdin else getattr(source, "name", "<events>")
    try:
        return _parse_events(source, name)
    except UnicodeDecodeError as exc:
        raise SourceError(f"not UTF-8 text: {exc.reason}", Location(name)) from None


def _step(macro: MacroStep, interp: Interpreter) -> SimulatedStep:
    return SimulatedStep(
        time=macro.time,
        event=macro.event.name if macro.event is not None else None,
        configuration=sorted(interp.configuration),
        entered=list(macro.entered_states),
        exited=list(macro.exited_states),
        sent=[(event.name, dict(event.data)) for event in macro.sent_events],
    )


def _what(exc: Exception) -> str:
    """What a failed step raised: an ExecutionError's message names its cause already."""
    return str(exc) if isinstance(exc, ExecutionError) else f"{type(exc).__name__}: {exc}"


def _execute(interp: Interpreter, steps: list[SimulatedStep], where: str) -> None:
    for _ in range(MAX_STEPS):
        try:
            macro = interp.execute_once()
        except Exception as exc:  # the step was rolled back; report it and go on
            failure = interp.last_failure
            steps.append(
                SimulatedStep(
                    time=interp.clock.time,  # when it was tried (the rollback restored the time)
                    event=failure.event.name if failure and failure.event else None,
                    configuration=sorted(interp.configuration),
                    entered=[],
                    exited=[],
                    error=f"{where}: step rolled back: {_what(exc)}",
                )
            )
            if failure is None or failure.event is None:
                return  # an eventless step failed: only the next event can change that
            continue
        if macro is None:
            return
        steps.append(_step(macro, interp))
    steps.append(  # an eventless cycle (or a timer that fires at once, forever): stop it
        SimulatedStep(
            time=interp.time,
            event=None,
            configuration=sorted(interp.configuration),
            entered=[],
            exited=[],
            error=f"{where}: the chart did not become stable after {MAX_STEPS} steps at time "
            f"{format_seconds(interp.time)} (an eventless transition cycle?); stopped there",
        )
    )


def simulate(
    chart: str | Path | Statechart,
    events: Iterable[TimedEvent] = (),
    *,
    until: float | None = None,
    initial_context: dict[str, Any] | None = None,
) -> list[SimulatedStep]:
    """Run ``chart`` over ``events`` on a simulated clock; one entry per macro step taken."""
    statechart = chart if isinstance(chart, Statechart) else load_statechart(chart)
    clock = SimulatedClock()
    try:
        interp = Interpreter(statechart, clock=clock, initial_context=initial_context)
    except Exception as exc:  # the preamble raised: the chart cannot start
        where = source_of(statechart)
        cause = exc.__cause__ or exc
        raise SourceError(
            f"the chart's preamble failed: {type(cause).__name__}: {cause}",
            (where.preamble or Location(where.file)) if where else Location(str(chart)),
        ) from None
    steps: list[SimulatedStep] = []
    _execute(interp, steps, "initial step")
    for event in events:
        clock.time = max(clock.time, event.time)
        if event.name is None:  # only the clock moves: the timers due by now fire
            _execute(interp, steps, f"time {format_seconds(event.time)} (line {event.line})")
            continue
        interp.context.update(event.context)
        interp.queue(event.name, **event.data)
        _execute(interp, steps, f"event '{event.name}' (line {event.line})")
    if until is not None and until > clock.time:
        clock.time = until
        _execute(interp, steps, f"time {format_seconds(until)}")
    return steps


def format_steps(steps: list[SimulatedStep], fmt: str = "text") -> str:
    """JSON lines (``fmt="json"``: what ``rasm simulate --format json`` prints) or a table."""
    if fmt == "json":  # failed (rolled-back) steps are not macro steps: the CLI reports them
        return "".join(json.dumps(step.as_dict()) + "\n" for step in steps if not step.error)
    out = []
    for step in steps:
        event = step.event if step.event is not None else "(no event)"
        if step.error:
            out.append(f"{format_seconds(step.time):>10}  {event:<20}  ROLLED BACK: {step.error}")
            continue
        out.append(f"{format_seconds(step.time):>10}  {event:<20}  {', '.join(step.configuration)}")
        if step.exited:
            out.append(f"{'':>10}  {'':<20}  - exited:  {', '.join(step.exited)}")
        if step.entered:
            out.append(f"{'':>10}  {'':<20}  + entered: {', '.join(step.entered)}")
        for name, data in step.sent:  # what a stage chart answers, with its data
            fields = ", ".join(f"{key}={value!r}" for key, value in data.items())
            out.append(f"{'':>10}  {'':<20}  > sent:    {name}({fields})")
    return "\n".join(out) + ("\n" if out else "")
