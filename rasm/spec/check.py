"""Offline checking (``rasm check``): a trace against a property file, and its reports.

Exit status convention (used by the command line): a property is *violated* if its value is
false at some judged record; *inconclusive* if it is never false but some value depends on
records after the end of the trace (or no record was ever judged); *satisfied* otherwise.
Only violations make ``rasm check`` fail (exit 1); inconclusive alone exits 0.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field

from rasm.spec.ast import Specification
from rasm.spec.explain import Explanation, explain
from rasm.spec.monitor import Monitor, PropertyRun
from rasm.spec.printer import format_value

__all__ = ["CheckReport", "PropertyReport", "check_records", "format_json", "format_text",
           "format_verdicts"]

EXPLAINED = 5  # violations explained in full per property in the text report
SUMMARISED = 100  # further violations explained in one line each


@dataclass
class PropertyReport:
    """One property over one trace."""

    name: str
    location: str
    verdict: str  # satisfied | violated | inconclusive
    violations: list[tuple[int, float]]
    judged: int
    inconclusive: int
    run: PropertyRun
    explanations: list[Explanation] = field(default_factory=list)


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
        return any(p.verdict == "violated" for p in self.properties)


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
        start = run.start or 0
        violations = [(start + k, times[start + k]) for k, v in enumerate(run.values) if v is False]
        undecided = sum(1 for v in run.values if v is None)
        if violations:
            verdict = "violated"
        elif undecided or not run.values:
            verdict = "inconclusive"
        else:
            verdict = "satisfied"
        reports.append(
            PropertyReport(prop.name, str(prop.location), verdict, violations, len(run.values),
                           undecided, run)
        )
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
    """SPEC §6: one JSON object."""
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
                }
                for p in report.properties
            ],
        }
    ) + "\n"


def format_verdicts(report: CheckReport) -> str:
    """SPEC §6: JSONL, one line per judged record and property."""
    lines = []
    for p in report.properties:
        start = p.run.start or 0
        for k, value in enumerate(p.run.values):
            index = start + k
            lines.append(json.dumps(
                {"property": p.name, "index": index, "time": report.times[index], "value": value}
            ))
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
    """A human report: each property's verdict; each violation explained (the first few)."""
    out = [f"{report.source}: {len(report.properties)} properties over {report.records} "
           f"records of {report.trace}"]
    for p in report.properties:
        if p.verdict == "violated":
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
        elif p.verdict == "inconclusive":
            if p.judged == 0:
                out.append(f"  {p.name}: inconclusive (no record judged: its signals never "
                           f"all had a value)  [{p.location}]")
            else:
                out.append(f"  {p.name}: inconclusive ({p.inconclusive} of {p.judged} records "
                           f"depend on records after the end of the trace)  [{p.location}]")
        else:
            out.append(f"  {p.name}: satisfied ({p.judged} records judged)")
    violated = sum(1 for p in report.properties if p.verdict == "violated")
    out.append(f"{violated} of {len(report.properties)} properties violated")
    return "\n".join(out) + "\n"
