"""What ``rasm run`` shows: a live view of modes, stages and verdicts, and the final summary."""

from __future__ import annotations

import time as _time
from typing import Any

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from rasm.platform.runtime import STAGES, Platform, RunSummary

__all__ = ["LiveView", "print_summary"]

_STYLE = {
    "satisfied": "green",
    "violated": "bold red",
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
        stats = p.ao.stats
        head = Text.assemble(
            (f"{p.manifest.name}", "bold"),
            f"  t={time:7.2f}s / {self.duration:g}s  ",
            f"iteration {stats.iterations}  stage {self.stage}  ",
            f"anomalies {stats.anomalies}  executed {stats.executed}  rejected {stats.rejected}",
        )
        modes = Table(show_header=True, header_style="bold", box=None)
        modes.add_column("block")
        modes.add_column("mode")
        for name, mode in p.sm.get_status().items():
            modes.add_row(name, Text(mode, style=_STYLE.get(mode, "")))
        verdicts = Table(show_header=True, header_style="bold", box=None)
        verdicts.add_column("property")
        verdicts.add_column("now")
        for name, value in sorted(p.tc.latest.items()):
            word = {True: "holds", False: "VIOLATED", None: "?"}[value]
            verdicts.add_row(name, Text(word, style="red" if value is False else "green"))
        grid = Table.grid(padding=(0, 4))
        grid.add_row(modes, verdicts)
        return Group(head, grid)


def print_summary(summary: RunSummary, console: Console) -> None:
    s = summary.stats
    stopped = f" (stopped by {summary.stopped_by})" if summary.stopped_by else ""
    console.print(
        f"[bold]{summary.app}[/bold]: {summary.duration:g} s on the {summary.clock} clock"
        f"{stopped}, "
        f"{s.iterations} loop iterations, {summary.records} trace records"
        + (f" -> {summary.trace}" if summary.trace else "")
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
    if s.failed_stages or s.timeouts:
        console.print(f"failed stages: {dict(s.failed_stages)}  overruns: {dict(s.timeouts)}")
    verdicts = Table(title="properties", show_header=True, header_style="bold")
    verdicts.add_column("property")
    verdicts.add_column("verdict")
    verdicts.add_column("violations", justify="right")
    for name, verdict in summary.verdicts.items():
        verdicts.add_row(
            name, Text(verdict, style=_STYLE.get(verdict, "")), str(summary.violations.get(name, 0))
        )
    console.print(verdicts)
    timing = Table(title="stage timing (ms)", show_header=True, header_style="bold")
    timing.add_column("stage")
    for q in ("p50", "p90", "p99"):
        timing.add_column(q, justify="right")
    for stage in STAGES:
        if stage in summary.timing:
            t = summary.timing[stage]
            timing.add_row(stage, *(f"{t[q] * 1000:.3f}" for q in ("p50", "p90", "p99")))
    console.print(timing)
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
