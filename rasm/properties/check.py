"""Offline checking (``rasm check``): a trace against a property file, and its reports.

Each property gets one of the five overall states of :mod:`rasm.properties.outcome` (satisfied,
violated, inconclusive, not judged, error). ``rasm check`` fails (exit 1) when some property is
violated, in error or not judged; satisfied and inconclusive alone exit 0.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field

from rasm.properties.ast import Specification
from rasm.properties.explain import Explanation, explain
from rasm.properties.monitor import Monitor, PropertyRun
from rasm.properties.outcome import (
    ERROR,
    INCONCLUSIVE,
    NOT_JUDGED,
    SATISFIED,
    VIOLATED,
    PropertyOutcome,
)
from rasm.properties.printer import format_value

__all__ = ["CheckReport", "PropertyReport", "check_records", "format_json", "format_text",
           "format_verdicts"]

# the order in which reports count the states: the failing ones first
STATE_ORDER = (VIOLATED, ERROR, NOT_JUDGED, INCONCLUSIVE, SATISFIED)
EXPLAINED = 5  # violations explained in full per property in the text report
SUMMARISED = 100  # further violations explained in one line each


@dataclass
class PropertyReport:
    """One property over one trace: its verdicts counted in ``outcome``, its violations and
    errors by record."""

    name: str
    location: str
    outcome: PropertyOutcome
    violations: list[tuple[int, float]]  # (index, time) of each violation (errors apart)
    run: PropertyRun
    explanations: list[Explanation] = field(default_factory=list)

    @classmethod
    def of(cls, name: str, location: str, run: PropertyRun, times: Sequence[float]):
        """The report of one property's run over a trace whose record times are ``times``."""
        start = run.start or 0
        errors = run.errors
        violated = [
            start + k for k, v in enumerate(run.values) if v is False and start + k not in errors
        ]
        outcome = PropertyOutcome(
            name,
            judged=len(run.values),
            violations=len(violated),
            errors=len(errors),
            inconclusive=sum(1 for v in run.values if v is None),
            first_error=errors[min(errors)] if errors else None,
            missing=tuple(run.missing) if run.start is None else (),
        )
        return cls(name, location, outcome, [(i, times[i]) for i in violated], run)

    @property
    def verdict(self) -> str:
        """The overall state: satisfied, violated, inconclusive, not judged or error."""
        return self.outcome.state

    @property
    def passed(self) -> bool:
        return self.outcome.passed

    @property
    def judged(self) -> int:
        return self.outcome.judged

    @property
    def inconclusive(self) -> int:
        return self.outcome.inconclusive

    @property
    def errors(self) -> dict[int, str]:
        """Record index -> why the property could not be evaluated there."""
        return self.run.errors

    @property
    def missing(self) -> tuple[str, ...]:
        """The signals that never had a value (when the property was never judged)."""
        return self.outcome.missing


@dataclass
class CheckReport:
    """Every property of a file over one trace."""

    source: str
    trace: str
    records: int
    properties: list[PropertyReport]
    times: Sequence[float] = ()

    @property
    def violated(self) -> bool:
        return any(p.verdict == VIOLATED for p in self.properties)

    @property
    def failed(self) -> list[PropertyReport]:
        """The properties that do not pass: violated, in error or not judged."""
        return [p for p in self.properties if not p.passed]


def check_records(
    spec: Specification,
    records: Sequence[tuple[float, dict]],
    *,
    trace: str = "<trace>",
    explain_violations: bool = True,
) -> CheckReport:
    """Run every property of ``spec`` over ``records`` (already read and checked)."""
    runs = Monitor(spec).run(records)
    times = [t for t, _ in records]
    reports = []
    for prop, run in zip(spec.properties, runs, strict=True):
        reports.append(PropertyReport.of(prop.name, str(prop.location), run, times))
    if explain_violations:
        limit = EXPLAINED + SUMMARISED
        wanted = {r.name: [i for i, _ in r.violations[:limit]] for r in reports if r.violations}
        if wanted:
            explanations = explain(spec, records, wanted)
            for report in reports:
                report.explanations = [
                    explanations[(report.name, i)] for i in wanted.get(report.name, [])
                ]
    return CheckReport(spec.source, trace, len(records), reports, times)


def format_json(report: CheckReport) -> str:
    """SPEC §6: one JSON object; ``verdict`` is one of the five states, ``errors`` counts the
    records where the property could not be evaluated (``first_error`` says why), ``missing``
    names the signals a property that was never judged waits for."""
    return json.dumps(
        {
            "records": report.records,
            "properties": [
                {
                    "name": p.name,
                    "verdict": p.verdict,
                    "violations": [{"index": i, "time": t} for i, t in p.violations],
                    "judged": p.judged,
                    "inconclusive": p.inconclusive,
                    "errors": p.outcome.errors,
                    "first_error": p.outcome.first_error,
                    "missing": list(p.missing),
                }
                for p in report.properties
            ],
        }
    ) + "\n"


def format_verdicts(report: CheckReport) -> str:
    """SPEC §6: JSONL, one line per judged record and property (``error`` on a record where
    the property could not be evaluated)."""
    lines = []
    for p in report.properties:
        start = p.run.start or 0
        errors = p.run.errors
        for k, value in enumerate(p.run.values):
            index = start + k
            line = {"property": p.name, "index": index, "time": report.times[index], "value": value}
            if index in errors:
                line["error"] = errors[index]
            lines.append(json.dumps(line))
    return "\n".join(lines) + ("\n" if lines else "")


def _one_line(e: Explanation) -> str:
    # the innermost reasons (the most indented lines, with the line they hang from) say the
    # most in the least space: "velocity <= 0.5 failed: velocity = 0.7"
    def depth(line: str) -> int:
        return len(line) - len(line.lstrip())

    deepest = max((depth(line) for line in e.lines), default=0)
    groups: list[list[str]] = []
    parent = None
    for line in e.lines:
        if depth(line) < deepest:
            parent = line.strip()
        elif groups and groups[-1][0] == parent:
            groups[-1].append(line.strip())
        else:
            groups.append([parent, line.strip()])
    parts = [
        (f"{g[0].rstrip(':')}: " if g[0] else "") + ", ".join(g[1:]) for g in groups
    ]
    text = "; ".join(parts)
    return text if len(text) <= 160 else text[:157] + "…"


def format_text(report: CheckReport) -> str:
    """A human report: each property's state; each violation explained (the first few), each
    error and each signal a property never saw named."""
    out = [f"{report.source}: {len(report.properties)} properties over {report.records} "
           f"records of {report.trace}"]
    for p in report.properties:
        state = p.verdict
        if state == VIOLATED:
            first_index, first_time = p.violations[0]
            out.append(
                f"  {p.name}: VIOLATED at {len(p.violations)} of {p.judged} judged records "
                f"(first: record {first_index}, time {first_time:g})  [{p.location}]"
            )
            for e in p.explanations[:EXPLAINED]:
                out.append(f"    at record {e.index} (time {e.time:g}):")
                out.extend("      " + line for line in e.lines)
                values = ", ".join(f"{k} = {format_value(v)}" for k, v in e.signals.items())
                if values:
                    out.append(f"      signals: {values}")
            for e in p.explanations[EXPLAINED:]:
                out.append(f"    at record {e.index} (time {e.time:g}): {_one_line(e)}")
            hidden = len(p.violations) - len(p.explanations)
            if hidden > 0:
                more = ", ".join(f"{i}" for i, _ in p.violations[len(p.explanations):][:20])
                tail = ", …" if hidden > 20 else ""
                out.append(f"    … and {hidden} more violations (records {more}{tail})")
            if p.errors:
                out.extend(_errors(p, report.times))
        elif state == ERROR:
            out.append(f"  {p.name}: ERROR at {len(p.errors)} of {p.judged} judged records: the "
                       f"checker could not evaluate it there  [{p.location}]")
            out.extend(_errors(p, report.times))
        elif state == NOT_JUDGED:
            why = (f"no value for {', '.join(p.missing)} in any record" if p.missing
                   else "no record reached it")
            out.append(f"  {p.name}: NOT JUDGED: {why}  [{p.location}]")
        elif state == INCONCLUSIVE:
            out.append(f"  {p.name}: inconclusive ({p.inconclusive} of {p.judged} records "
                       f"depend on records after the end of the trace)  [{p.location}]")
        else:
            out.append(f"  {p.name}: satisfied ({p.judged} records judged)")
    out.append(_tally_line(report))
    return "\n".join(out) + "\n"


def _errors(p: PropertyReport, times: Sequence[float]) -> list[str]:
    """The first records where ``p`` could not be evaluated, and why."""
    indices = sorted(p.errors)
    out = [f"    in error at record {i} (time {times[i]:g}): {p.errors[i]}" for i in indices[:5]]
    if len(indices) > 5:
        more = ", ".join(str(i) for i in indices[5:25])
        tail = ", …" if len(indices) > 25 else ""
        out.append(f"    … and in error at {len(indices) - 5} more records ({more}{tail})")
    return out


def _tally_line(report: CheckReport) -> str:
    """``1 of 3 properties fail: 1 not judged, 2 satisfied``."""
    counts = {state: 0 for state in STATE_ORDER}
    for p in report.properties:
        counts[p.verdict] += 1
    states = ", ".join(f"{n} {state}" for state, n in counts.items() if n)
    return f"{len(report.failed)} of {len(report.properties)} properties fail" + (
        f": {states}" if states else ""
    )
