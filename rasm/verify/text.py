"""``rasm verify``'s text output: the verdict, then each property and problem with its
counterexample as a step table (event, data, clock, configuration) and, for a property, the
sub-formula that failed."""

from __future__ import annotations

import json

from rasm.statechart.simulate import SimulatedStep
from rasm.times import format_seconds
from rasm.verify.chart import Counterexample, Verification

__all__ = ["format_verification"]


def _steps_table(cex: Counterexample) -> list[str]:
    lines = [f"      {'time':>8}  {'event':<22} {'data':<24} configuration after the step"]
    for step in cex.steps:
        lines.append("      " + _row(step, cex))
    return lines


def _data_of(step: SimulatedStep, cex: Counterexample) -> str:
    for move in cex.moves:
        if move.event == step.event and move.data:
            return json.dumps(dict(move.data))
    return ""


def _row(step: SimulatedStep, cex: Counterexample) -> str:
    time = format_seconds(step.time)
    event = step.event if step.event is not None else "(no event)"
    if step.error:
        return f"{time:>8}  {event:<22} {'':<24} ROLLED BACK: {step.error}"
    data = _data_of(step, cex) if step.event is not None else ""
    return f"{time:>8}  {event:<22} {data:<24} {', '.join(step.configuration)}"


def _counterexample(cex: Counterexample, chart: str) -> list[str]:
    lines = ["    counterexample (events for rasm simulate " + chart + " --events FILE):"]
    lines.extend("      " + json.dumps(line) for line in cex.events() or [])
    if not cex.moves:
        lines.append("      (none: the initial step)")
    lines.append("    steps:")
    lines.extend(_steps_table(cex))
    if cex.explanation:
        lines.append("    why:")
        lines.extend("      " + line for line in cex.explanation)
    return lines


def format_verification(result: Verification) -> str:
    how = "complete" if result.complete else f"stopped at --max-states {result.max_states}"
    out = [
        f"{result.chart}: {result.verdict} ({result.states} states, {result.transitions} "
        f"transitions, {how})",
        f"  environment: {result.environment}",
    ]
    for prop in result.properties:
        out.append(f"  property {prop.name}: {prop.verdict}")
        if prop.counterexample is not None:
            out.extend(_counterexample(prop.counterexample, result.chart))
    for finding in result.problems:
        out.append(f"  {finding.kind}: {finding.message}")
        if finding.counterexample is not None and finding.kind not in ("unreachable",):
            out.extend(_counterexample(finding.counterexample, result.chart))
    if result.verdict == "inconclusive":
        out.append(
            f"  inconclusive: more than {result.max_states} states (unbounded data, or a larger "
            "--max-states needed); nothing above is proved for the states not explored"
        )
    return "\n".join(out) + "\n"
