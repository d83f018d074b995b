"""Verdict timelines: each property's value over time, its violations and their explanations.

Offline (:func:`check_trace`) the trace is checked with ``rasm check``'s own functions, so the
report says what ``rasm check`` says; online (:class:`VerdictTimeline` fed the Trustworthiness
Checker's verdicts) the dashboard shows what the monitors decided so far.

A timeline is a list of runs ``[from, to, value]`` where value is ``true`` (holds), ``false``
(violated), ``null`` (inconclusive), ``"error"`` (the property could not be evaluated there) or
``"warm-up"`` (not judged yet: a signal it reads has no value), plus the violations ``{"time",
"index", "explanation", "signals"}``, the overall verdict, one of the five states of
:mod:`rasm.properties.outcome`, and the violations grouped into *episodes*: a stretch of
consecutive judged records at which the property is violated, from its first violated record
until the first record at which it no longer is (``until``; None while it still is, at the end
of the trace), with how many records it spans. One 0.3 s near miss is one episode, not twenty
violations; the first record of each episode is the one explained.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any

from rasm.errors import read_utf8
from rasm.properties.ast import Specification
from rasm.properties.check import check_records
from rasm.properties.explain import explain
from rasm.properties.loader import load_specification, signals_of
from rasm.properties.outcome import PropertyOutcome
from rasm.trace import read_trace

__all__ = ["EXPLAINED", "VerdictTimeline", "check_trace", "load_properties"]

EXPLAINED = 20  # violations explained per property (the others are marked, not explained)


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
    episodes: list[dict[str, Any]] = field(default_factory=list)
    file: str = ""  # the property file, as shown

    def __post_init__(self) -> None:
        self.outcome.name = self.name
        self._violating = False  # the latest judged record was a violation

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

    def add(self, time: float, value: bool | None | str, error: str | None = None,
            index: int | None = None) -> None:
        """Extend the timeline with the verdict at ``time`` (records in time order): its value,
        or ``"warm-up"``; ``error`` says why the property could not be evaluated there;
        ``index`` is the record's, where known."""
        if value != "warm-up":
            self.outcome.add(value, error)
            if error is not None:
                value = "error"
            violated = value is False
            if violated:
                self.violations.append({"time": time, "index": index})
                if self.max_violations is not None and len(self.violations) > self.max_violations:
                    del self.violations[0]
            self._episode(time, index, violated)
        if self.runs and self.runs[-1][2] == value:
            self.runs[-1][1] = time
        else:
            if self.runs:
                self.runs[-1][1] = time
            self.runs.append([time, time, value])

    def _episode(self, time: float, index: int | None, violated: bool) -> None:
        """Group the verdict at ``time`` into the episodes of consecutive violations."""
        if violated and self._violating:
            episode = self.episodes[-1]
            episode["end"], episode["last"] = time, index
            episode["count"] += 1
        elif violated:
            self.episodes.append({"start": time, "end": time, "until": None, "first": index,
                                  "last": index, "count": 1})
            if self.max_violations is not None and len(self.episodes) > self.max_violations:
                del self.episodes[0]
        elif self._violating:
            self.episodes[-1]["until"] = time  # it holds again (or is in error, inconclusive)
        self._violating = violated

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able timeline (a copy)."""
        return {
            "name": self.name,
            "source": self.source,
            "reads": list(self.reads),
            "runs": [list(run) for run in self.runs],
            "violations": [dict(v) for v in self.violations],  # the last ones, if bounded
            "episodes": [dict(e) for e in self.episodes],  # the last ones, if bounded
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
    """Check ``trace`` against every property of ``specs``: one timeline per property, the
    first record of each of its first :data:`EXPLAINED` episodes explained."""
    out = []
    for spec in specs:
        records = read_trace(trace, spec.signals)  # type errors name the trace's line
        report = check_records(spec, records, trace=str(trace), explain_violations=False)
        times = report.times
        timelines = []
        for prop, result in zip(spec.properties, report.properties, strict=True):
            timeline = VerdictTimeline(
                prop.name, str(prop.location), sorted(signals_of(prop.formula)), file=spec.source
            )
            start = result.run.start
            if start is None:
                start = len(times)
            for index in range(min(start, len(times))):
                timeline.add(times[index], "warm-up")
            for k, value in enumerate(result.run.values):
                index = start + k
                timeline.add(times[index], value, result.errors.get(index), index)
            if times and timeline.runs:
                timeline.runs[-1][1] = times[-1]
            timeline.outcome.missing = result.missing
            timeline.outcome.vacuous = result.outcome.vacuous
            timelines.append(timeline)
        wanted = {t.name: [e["first"] for e in t.episodes[:EXPLAINED]]
                  for t in timelines if t.episodes}
        explanations = explain(spec, records, wanted)
        for timeline in timelines:
            for entry in [*timeline.episodes[:EXPLAINED], *timeline.violations]:
                index = entry["first"] if "first" in entry else entry["index"]
                found = explanations.get((timeline.name, index))
                if found is not None:
                    entry["explanation"] = list(found.lines)
                    entry["signals"] = dict(found.signals)
        out += timelines
    _distinct_names(out)
    return out


def _distinct_names(timelines: Sequence[VerdictTimeline]) -> None:
    """Two files may name a property alike: such names get their file's name appended."""
    seen: dict[str, int] = {}
    for timeline in timelines:
        seen[timeline.name] = seen.get(timeline.name, 0) + 1
    for timeline in timelines:
        if seen[timeline.name] > 1:
            timeline.name = f"{timeline.name} ({PurePath(timeline.file).name})"
