"""Verdict timelines: each property's value over time, its violations and their explanations.

Offline (:func:`check_trace`) the trace is checked with ``rasm check``'s own functions, so the
report says what ``rasm check`` says; online (:class:`VerdictTimeline` fed the Trustworthiness
Checker's verdicts) the dashboard shows what the monitors decided so far.

A timeline is a list of runs ``[from, to, value]`` where value is ``true`` (holds), ``false``
(violated), ``null`` (inconclusive), ``"error"`` (the property could not be evaluated there) or
``"warm-up"`` (not judged yet: a signal it reads has no value), plus the violations ``{"time",
"index", "explanation", "signals"}`` and the overall verdict, one of the five states of
:mod:`rasm.properties.outcome`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import read_utf8
from rasm.properties.ast import Specification
from rasm.properties.check import check_records
from rasm.properties.explain import explain
from rasm.properties.loader import load_specification, signals_of
from rasm.properties.outcome import PropertyOutcome
from rasm.resources import data_dir
from rasm.trace import read_trace

__all__ = ["EXPLAINED", "VerdictTimeline", "check_trace", "load_properties", "platform_properties"]

EXPLAINED = 20  # violations explained per property (the others are marked, not explained)


def platform_properties() -> list[Path]:
    """The platform's own property files: every trace ``rasm run`` writes is subject to them."""
    return sorted(data_dir("properties").glob("*.rv"))


def load_properties(paths: Sequence[str | Path]) -> list[Specification]:
    """Load property files (errors name the file, line and column)."""
    specs = []
    for path in paths:
        text = read_utf8(path)
        specs.append(load_specification(text, source=str(path)))
    return specs


@dataclass
class VerdictTimeline:
    """One property's verdicts over time, compressed into runs of equal value; ``outcome``
    counts them (its state is the property's overall verdict so far)."""

    name: str
    source: str
    reads: list[str] = field(default_factory=list)
    runs: list[list[Any]] = field(default_factory=list)
    violations: list[dict[str, Any]] = field(default_factory=list)
    max_violations: int | None = None
    outcome: PropertyOutcome = field(default_factory=lambda: PropertyOutcome(""))

    def __post_init__(self) -> None:
        self.outcome.name = self.name

    @property
    def verdict(self) -> str:
        """satisfied, violated, inconclusive, not judged or error."""
        return self.outcome.state

    @property
    def judged(self) -> int:
        return self.outcome.judged

    @property
    def inconclusive(self) -> int:
        return self.outcome.inconclusive

    def add(self, time: float, value: bool | None | str, error: str | None = None) -> None:
        """Extend the timeline with the verdict at ``time`` (records in time order): its value,
        or ``"warm-up"``; ``error`` says why the property could not be evaluated there."""
        if value != "warm-up":
            self.outcome.add(value, error)
            if error is not None:
                value = "error"
            elif value is False:
                self.violations.append({"time": time, "index": None})
                if self.max_violations is not None and len(self.violations) > self.max_violations:
                    del self.violations[0]
        if self.runs and self.runs[-1][2] == value:
            self.runs[-1][1] = time
        else:
            if self.runs:
                self.runs[-1][1] = time
            self.runs.append([time, time, value])

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able timeline (a copy)."""
        return {
            "name": self.name,
            "source": self.source,
            "reads": list(self.reads),
            "runs": [list(run) for run in self.runs],
            "violations": [dict(v) for v in self.violations],  # the last ones, if bounded
            "violated": self.outcome.violations,  # how many, all told
            "judged": self.judged,
            "inconclusive": self.inconclusive,
            "errors": self.outcome.errors,
            "first_error": self.outcome.first_error,
            "missing": list(self.outcome.missing),
            "verdict": self.verdict,
            "word": self.outcome.word,  # the verdict, "satisfied (vacuously: …)" where it is
            "vacuous": [u.text for u in self.outcome.vacuous],
            "describe": self.outcome.describe(),
        }


def check_trace(specs: Sequence[Specification], trace: str | Path) -> list[VerdictTimeline]:
    """Check ``trace`` against every property of ``specs``: one timeline per property."""
    out = []
    for spec in specs:
        records = read_trace(trace, spec.signals)  # type errors name the trace's line
        report = check_records(spec, records, trace=str(trace), explain_violations=False)
        times = report.times
        wanted = {p.name: [i for i, _ in p.violations[:EXPLAINED]] for p in report.properties}
        explanations = explain(spec, records, {k: v for k, v in wanted.items() if v})
        for prop, result in zip(spec.properties, report.properties, strict=True):
            timeline = VerdictTimeline(
                prop.name, str(prop.location), sorted(signals_of(prop.formula))
            )
            start = result.run.start
            if start is None:
                start = len(times)
            for index in range(min(start, len(times))):
                timeline.add(times[index], "warm-up")
            for k, value in enumerate(result.run.values):
                timeline.add(times[start + k], value, result.errors.get(start + k))
            if times and timeline.runs:
                timeline.runs[-1][1] = times[-1]
            timeline.outcome.missing = result.missing
            timeline.outcome.vacuous = result.outcome.vacuous
            timeline.violations = []
            for index, time in result.violations:
                entry: dict[str, Any] = {"time": time, "index": index}
                found = explanations.get((prop.name, index))
                if found is not None:
                    entry["explanation"] = list(found.lines)
                    entry["signals"] = {k: v for k, v in found.signals.items()}
                timeline.violations.append(entry)
            out.append(timeline)
    _distinct_names(out)
    return out


def _distinct_names(timelines: Sequence[VerdictTimeline]) -> None:
    """Two files may name a property alike: such names get their file's name appended."""
    seen: dict[str, int] = {}
    for timeline in timelines:
        seen[timeline.name] = seen.get(timeline.name, 0) + 1
    for timeline in timelines:
        if seen[timeline.name] > 1:
            file = Path(timeline.source.split(":")[0]).name
            timeline.name = f"{timeline.name} ({file})"
