"""What ``rasm run`` shows: a live view of modes, stages and verdicts, and the final summary."""

from __future__ import annotations

import time as _time
from typing import Any

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from rasm.loop import STAGES
from rasm.platform.platform import Platform
from rasm.platform.run_options import Role
from rasm.platform.summary import RunSummary
from rasm.properties.monitor import Verdict
from rasm.properties.outcome import PASSING
from rasm.times import format_seconds

__all__ = ["LiveView", "print_summary", "timeline_note"]

_STYLE = {
    "satisfied": "green",
    "violated": "bold red",
    "error": "bold red",
    "not judged": "bold yellow",
    "inconclusive": "yellow",
    "initialized": "green",
    "fault": "bold red",
    "terminated": "dim",
}


class LiveView:
    """Refreshes a compact dashboard at most ``fps`` times a second of wall time, from the loop's
    own records (no extra thread reads the platform's state while it changes)."""

    def __init__(
        self, platform: Platform, console: Console, *, duration: float, fps: float = 4.0
    ) -> None:
        self.platform = platform
        self.console = console
        self.duration = duration
        self.period = 1.0 / fps
        self.last = 0.0
        self.stage = "-"
        self.live = Live(console=console, auto_refresh=False, transient=True)

    def __enter__(self) -> LiveView:
        self.platform.on_record.append(self.on_record)
        self.live.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.live.__exit__(*exc)

    def on_record(self, time: float, record: dict[str, Any]) -> None:
        if "stage" in record:
            self.stage = record["stage"]
        now = _time.monotonic()
        if now - self.last >= self.period:
            self.last = now
            self.live.update(self.render(time), refresh=True)

    def render(self, time: float) -> Group:
        p = self.platform
        stats = p.managing.adaptation_orchestrator.stats
        start = p.timeline_start
        head = Text.assemble(
            (f"{p.manifest.name}", "bold"),
            f"  t={time - start:7.2f}s / {format_seconds(self.duration)}s  ",
            f"iteration {stats.iterations}  stage {self.stage}  ",
            f"anomalies {stats.anomalies}  executed {stats.executed}  rejected {stats.rejected}",
        )
        lines: list[Any] = [head]
        if p.restored_from is not None:
            # the trace's times go on from the persisted knowledge: say so, or t looks wrong
            lines.append(Text(timeline_note(p, time), style="dim"))
        modes = Table(show_header=True, header_style="bold", box=None)
        modes.add_column("block")
        modes.add_column("mode")
        for name, mode in p.assembly.state_manager.get_status().items():
            modes.add_row(name, Text(mode, style=_STYLE.get(mode, "")))
        verdicts = Table(show_header=True, header_style="bold", box=None)
        verdicts.add_column("property")
        verdicts.add_column("now")
        for name in sorted(p.managing.trustworthiness_checker.outcomes):
            word, style = _now(p.managing.trustworthiness_checker.latest_verdict(name))
            verdicts.add_row(name, Text(word, style=style))
        grid = Table.grid(padding=(0, 4))
        grid.add_row(modes, verdicts)
        return Group(*lines, grid)


def timeline_note(platform: Platform, time: float | None = None) -> str:
    """Where a live run's timeline comes from, when it continues persisted knowledge."""
    start = format_seconds(platform.timeline_start)
    now = f"; trace time now {format_seconds(time)} s" if time is not None else ""
    return (
        f"timeline continued from {platform.restored_from} (knowledge up to t={start} s): "
        f"this run's trace times start at {start} s{now}"
    )


def _now(verdict: Verdict | None) -> tuple[str, str]:
    """A property's latest verdict in a word, and its style: only "holds" is green."""
    if verdict is None:
        return "not judged yet", "yellow"
    if verdict.error is not None:
        return "ERROR", "bold red"
    if verdict.value is False:
        return "VIOLATED", "bold red"
    if verdict.value is None:
        return "inconclusive", "yellow"
    return "holds", "green"


def print_summary(summary: RunSummary, console: Console) -> None:
    if summary.role is Role.MANAGED:
        _managed_summary(summary, console)
    else:
        _loop_summary(summary, console)
    _refusals_and_failures(summary, console)


def _managed_summary(summary: RunSummary, console: Console) -> None:
    """A managed-only process (``--role managed``): what the managed side did; the loop, its
    properties and its timing are the managing process's to report."""
    stopped = f" (stopped by {summary.stopped_by})" if summary.stopped_by else ""
    console.print(
        f"[bold]{summary.app}[/bold]: {format_seconds(summary.duration)} s on the "
        f"{summary.clock} clock{stopped}, the managed side only (--role managed: the loop, "
        "its properties and its verdicts are the managing process's)",
        soft_wrap=True,
    )
    lines = summary.managed or ["no simulator ran here (managed_system.simulator)"]
    console.print("managed system:")
    for line in lines:
        console.print(Text(f"  {line}"), soft_wrap=True)


def _loop_summary(summary: RunSummary, console: Console) -> None:
    s = summary.stats
    stopped = f" (stopped by {summary.stopped_by})" if summary.stopped_by else ""
    console.print(
        f"[bold]{summary.app}[/bold]: {format_seconds(summary.duration)} s on the "
        f"{summary.clock} clock"
        f"{stopped}, "
        f"{s.iterations} loop iterations, {summary.records} trace records"
        + (f" -> {summary.trace}" if summary.trace else ""),
        soft_wrap=True,  # one line however long the trace's path: scripts and guides read it
    )
    counts = Table(title="adaptations", show_header=True, header_style="bold")
    for name in ("anomalies", "plans", "accepted", "rejected", "executed", "dropped", "cancelled"):
        counts.add_column(name, justify="right")
    counts.add_row(
        *(
            str(getattr(s, n))
            for n in (
                "anomalies",
                "plans",
                "accepted",
                "rejected",
                "executed",
                "dropped",
                "cancelled",
            )
        )
    )
    console.print(counts)
    if summary.fallback_engagements is not None:
        console.print(
            f"fallback engaged {summary.fallback_engagements} "
            f"time{'' if summary.fallback_engagements == 1 else 's'}"
        )
    for name, calls in summary.calls.items():
        # a call's failure fails its action: counted here, each in the trace with its reason
        line = f"effector {name} calls: {calls.describe()}"
        if calls.last_failure:
            line += f" (last failure: {calls.last_failure})"
        console.print(Text(line), soft_wrap=True)
    if s.failed_stages or s.timeouts:
        console.print(f"failed stages: {dict(s.failed_stages)}  overruns: {dict(s.timeouts)}")
    verdicts = Table(title="properties", show_header=True, header_style="bold")
    verdicts.add_column("property", no_wrap=True)
    verdicts.add_column("verdict", no_wrap=True)
    verdicts.add_column("judged", justify="right")
    verdicts.add_column("violations", justify="right")
    verdicts.add_column("errors", justify="right")
    for name, state in summary.verdicts.items():
        outcome = summary.outcomes.get(name)
        vacuous = outcome is not None and outcome.passed and bool(outcome.vacuous)
        verdicts.add_row(
            name,
            Text(f"{state}*" if vacuous else state, style=_STYLE.get(state, "")),
            str(outcome.judged) if outcome else "",
            str(summary.violations.get(name, 0)),
            str(outcome.errors) if outcome else "",
        )
    console.print(verdicts)
    if summary.off:
        console.print(f"not checked (off in app.yaml): {', '.join(summary.off)}", soft_wrap=True)
    untested = [o for o in summary.outcomes.values() if o.passed and o.vacuous]
    if untested:
        # passing, but part of the property was never put to the test: say what never happened
        console.print("* never put to the test:")
        for outcome in untested:
            console.print(f"  {outcome.name}: {outcome.word}", soft_wrap=True, markup=False)
    failing = [name for name, state in summary.verdicts.items() if state not in PASSING]
    if failing:
        # one line each, never wrapped: the signal names and the error are what to act on
        console.print(
            f"[bold red]{len(failing)} of {len(summary.verdicts)} properties not satisfied[/]: "
            + ", ".join(f"{name} ({summary.verdicts[name]})" for name in failing),
            soft_wrap=True,
        )
        for name in failing:
            outcome = summary.outcomes.get(name)
            if outcome is not None:
                console.print(f"  {name}: {outcome.describe()}", soft_wrap=True, markup=False)
    timing = Table(title="stage timing (ms)", show_header=True, header_style="bold")
    timing.add_column("stage")
    for q in ("p50", "p90", "p99"):
        timing.add_column(q, justify="right")
    for stage in STAGES:
        if stage in summary.timing:
            t = summary.timing[stage]
            timing.add_row(stage, *(f"{t[q] * 1000:.3f}" for q in ("p50", "p90", "p99")))
    console.print(timing)


def _refusals_and_failures(summary: RunSummary, console: Console) -> None:
    if summary.rejected_data:
        console.print(f"rejected managed-system data: {summary.rejected_data}")
    if summary.bus:
        console.print(f"refused from the bus: {summary.bus}")
    if summary.repeated_failures:
        console.print("failures logged in full once, then counted:")
        for what, count in summary.repeated_failures.items():
            console.print(Text(f"  {count} × {what}"))
    if summary.missed_iterations:
        console.print(
            f"loop iterations skipped (the loop was still busy when they fell due): "
            f"{summary.missed_iterations}"
        )
    if summary.write_failures:
        # the exit code is 1 for these: say plainly what is missing, one line each
        console.print("[bold red]writes that failed[/] (the run went on without them):",
                      soft_wrap=True)
        for failure in summary.write_failures:
            console.print(Text(f"  {failure.describe()}"), soft_wrap=True)
    if summary.damage:
        console.print("[bold red]damaged recording[/] (what could not be replayed):",
                      soft_wrap=True)
        for damage in summary.damage:
            console.print(Text(f"  {damage.describe()}"), soft_wrap=True)
