"""``rasm verify CHART``: explore a chart completely and judge it (SPEC §11).

:func:`verify_chart` loads the chart, the environment and the properties, explores
(:mod:`rasm.verify.explore`) and turns what it found into a :class:`Verification`: the verdict,
the reachable configurations, the unreachable states, each property's verdict and each problem,
with a shortest counterexample in ``rasm simulate``'s events format. Each counterexample is
replayed with ``rasm simulate``'s own function before it is reported, and its step table is what
that replay printed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sismic.model import Statechart

from rasm.errors import Location, SourceError, SourceErrors, read_utf8
from rasm.statechart.load import load_statechart
from rasm.statechart.simulate import SimulatedStep, TimedEvent, simulate
from rasm.times import format_nanoseconds, from_nanoseconds
from rasm.verify.environment import Environment, default_environment, load_environment
from rasm.verify.explore import ChartExplorer, Move, Problem, explore
from rasm.verify.interfaces import receives
from rasm.verify.past import PastProperty, calls, explain, load_past_properties

__all__ = ["Counterexample", "Finding", "PropertyVerdict", "Verification", "verify_chart"]

DEFAULT_MAX_STATES = 100_000


@dataclass
class Counterexample:
    """A path to a problem: the environment's moves, and the steps the chart took on them."""

    moves: list[Move]
    steps: list[SimulatedStep]
    explanation: list[str] = field(default_factory=list)

    def events(self) -> list[dict[str, Any]]:
        """The moves as lines of ``rasm simulate``'s events format."""
        return [move.as_line() for move in self.moves]

    def jsonl(self) -> str:
        return "".join(json.dumps(line) + "\n" for line in self.events())


@dataclass
class PropertyVerdict:
    name: str
    verdict: str  # satisfied | violated | inconclusive
    counterexample: Counterexample | None = None
    location: Location | None = None


@dataclass
class Finding:
    """A built-in problem: raising code, non-determinism, contract, no stable state,
    unreachable, stuck."""

    kind: str
    message: str
    counterexample: Counterexample | None = None


@dataclass
class Verification:
    """What ``rasm verify`` says of a chart."""

    chart: str
    verdict: str  # satisfied | violated | inconclusive
    complete: bool
    states: int
    transitions: int
    reachable: list[list[str]]
    unreachable: list[str]
    properties: list[PropertyVerdict]
    problems: list[Finding]
    environment: str
    max_states: int

    @property
    def exit_code(self) -> int:
        return {"satisfied": 0, "violated": 1, "inconclusive": 3}[self.verdict]

    def as_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict,
            "complete": self.complete,
            "states": self.states,
            "transitions": self.transitions,
            "reachable": self.reachable,
            "unreachable": self.unreachable,
            "properties": [
                {
                    "name": p.name,
                    "verdict": p.verdict,
                    "counterexample": p.counterexample.events() if p.counterexample else [],
                }
                for p in self.properties
            ],
            "problems": [
                {
                    "kind": f.kind,
                    "message": f.message,
                    "counterexample": f.counterexample.events() if f.counterexample else [],
                }
                for f in self.problems
            ],
        }


def _replay(
    statechart: Statechart, moves: list[Move], context: dict[str, Any] | None
) -> list[SimulatedStep]:
    events = [
        TimedEvent(from_nanoseconds(m.time_ns), m.event, dict(m.data), line=i + 1)
        for i, m in enumerate(moves)
    ]
    return simulate(statechart, events, initial_context=dict(context or {}))


def _counterexample(
    statechart: Statechart, problem: Problem, context: dict[str, Any] | None
) -> Counterexample:
    moves = problem.path or []
    return Counterexample(moves, _replay(statechart, moves, context))


def verify_chart(
    chart: str | Path,
    *,
    environment: str | Path | None = None,
    properties: str | Path | None = None,
    max_states: int = DEFAULT_MAX_STATES,
    initial_context: dict[str, Any] | None = None,
) -> Verification:
    """Verify the chart at ``chart``: see the module docstring. Bad input raises
    :class:`~rasm.errors.SourceError` (or ``SourceErrors``) at its place."""
    if max_states < 1:
        raise SourceError("--max-states must be at least 1", Location("--max-states"))
    statechart = load_statechart(chart)
    props: list[PastProperty] = []
    if properties is not None:
        props = load_past_properties(read_utf8(properties), source=str(properties))
    explorer = ChartExplorer(
        statechart, Environment(()), props, initial_context=initial_context
    )
    if environment is not None:
        env = load_environment(environment)
    else:
        env = default_environment(
            explorer.code, receives(chart, statechart, explorer.code.events)
        )
    explorer.environment = env
    _check_names(props, statechart, env, explorer.code.sends)
    found = explore(explorer, max_states=max_states)
    property_verdicts = []
    for prop in props:
        problem = found.violated.get(prop.name)
        if problem is not None:
            cex = _counterexample(statechart, problem, initial_context)
            cex.explanation = _explain_on_replay(statechart, prop, cex, initial_context)
            property_verdicts.append(PropertyVerdict(prop.name, "violated", cex, prop.location))
        else:
            verdict = "satisfied" if found.complete else "inconclusive"
            property_verdicts.append(PropertyVerdict(prop.name, verdict, None, prop.location))
    findings = [
        Finding(p.kind, p.message, _counterexample(statechart, p, initial_context))
        for p in found.problems
    ]
    unreachable: list[str] = []
    if found.complete:
        unreachable = sorted(set(statechart.states) - found.entered)
        findings.extend(
            Finding("unreachable", f"state {name!r} is entered on no path") for name in unreachable
        )
    if findings or any(p.verdict == "violated" for p in property_verdicts):
        verdict = "violated"
    elif not found.complete:
        verdict = "inconclusive"
    else:
        verdict = "satisfied"
    return Verification(
        chart=str(chart),
        verdict=verdict,
        complete=found.complete,
        states=found.states,
        transitions=found.transitions,
        reachable=sorted(sorted(conf) for conf in found.configurations),
        unreachable=unreachable,
        properties=property_verdicts,
        problems=findings,
        environment=env.describe(),
        max_states=max_states,
    )


def _check_names(
    props: list[PastProperty], statechart: Statechart, env: Environment, sends: set[str]
) -> None:
    """A state, event or sent event a property names that the chart and environment do not
    have is a typo that would make the property vacuous: refused at its place."""
    known = {
        "in_state": (set(statechart.states), "a state of the chart"),
        "received": (
            {e.name for e in env.events} | sends, "an event the environment or the chart sends"
        ),
        "sent": (sends, "an event the chart's code sends (send('name'))"),
    }
    errors = []
    for prop in props:
        for call in calls(prop):
            names, what = known[call.func]
            name = call.args[0].value
            if name not in names:
                errors.append(SourceError(
                    f"{call.func}({name!r}): {name!r} is not {what}", call.location
                ))
    if errors:
        raise SourceErrors(errors)


def _explain_on_replay(
    statechart: Statechart, prop: PastProperty, cex: Counterexample,
    initial_context: dict[str, Any] | None,
) -> list[str]:
    """The property's failing sub-formula on the counterexample, judged on a fresh run of it."""
    explorer = ChartExplorer(statechart, Environment(()), [prop], initial_context=initial_context)
    records, _, _ = explorer.start()
    for move in cex.moves:
        more, _, _ = explorer.apply(move)
        records.extend(more)
    state = prop.initial()
    last: int | None = None
    for record in records:
        dt = None if last is None else record.time_ns - last
        value, new = prop.step(state, record, dt)
        if not value:
            step = f"the step of {record.received}" if record.received else "an eventless step"
            where = f"at t={format_nanoseconds(record.time_ns)}, on {step}:"
            return [where, *explain(prop, state, record, dt)]
        state, last = new, record.time_ns
    return []
