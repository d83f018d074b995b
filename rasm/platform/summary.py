"""What a run of the loop comes to: the summary ``rasm run`` prints at the end."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rasm.comm import Transport
from rasm.loop import STAGES
from rasm.losses import Damage, WriteFailure
from rasm.platform.adaptation_orchestrator import AdaptationOrchestrator
from rasm.platform.calls import CallCounts
from rasm.platform.distribution import Distribution
from rasm.platform.fallback import FallbackSwitch
from rasm.platform.managed_system import ManagedSystem, describe_activity
from rasm.platform.protocols import LoopStats
from rasm.platform.run_options import Role
from rasm.platform.state_manager import StateManager
from rasm.platform.telegraf import Telegraf
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.properties.outcome import PASSING, PropertyOutcome
from rasm.trace import TraceWriter

__all__ = ["RunSummary", "bus_refusals", "summarise"]


@dataclass
class RunSummary:
    """What ``rasm run`` prints at the end."""

    app: str
    clock: str
    duration: float
    stats: LoopStats
    verdicts: dict[str, str]  # property -> satisfied | violated | inconclusive | not judged | error
    violations: dict[str, int]
    timing: dict[str, dict[str, float]]
    records: int
    rejected_data: dict[str, int] = field(default_factory=dict)
    # what the bus brought that was refused: malformed messages, actions the effector gate
    # refused (unsigned, bad signature, replayed), updates refused (only the non-zero counts)
    bus: dict[str, int] = field(default_factory=dict)
    modes: dict[str, str] = field(default_factory=dict)
    trace: str | None = None
    # loop iterations skipped on the wall clock because the loop was still busy when they fell due
    missed_iterations: int = 0
    # what ended the run before its duration (e.g. "SIGTERM"), None if it ran to the end
    stopped_by: str | None = None
    # each failure logged more than once (shown once, then counted): how many times in all
    repeated_failures: dict[str, int] = field(default_factory=dict)
    # every property's verdicts counted: the state, the errors, the signals never seen
    outcomes: dict[str, PropertyOutcome] = field(default_factory=dict)
    # how often the fallback switch engaged (None: the app has no fallback)
    fallback_engagements: int | None = None
    # the files (or servers) that refused writes: the trace, knowledge, timing, log files
    write_failures: list[WriteFailure] = field(default_factory=list)
    # the parts of a replayed recording that could not be read
    damage: list[Damage] = field(default_factory=list)
    # the platform properties the app turned off (platform_properties: in app.yaml): not checked
    off: tuple[str, ...] = ()
    # per service or action effector, how its calls ended
    calls: dict[str, CallCounts] = field(default_factory=dict)
    # all, managing or managed: which side of the system this process ran
    role: Role = Role.ALL
    # what the managed side (the app's simulator) did, one line each (empty: none ran here)
    managed: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """No property violated, in error or not judged (inconclusive alone passes), no write
        failed and nothing replayed was damaged: what the run promised to keep is all there."""
        return (all(state in PASSING for state in self.verdicts.values())
                and not self.write_failures and not self.damage)

    def properties(self) -> list[dict[str, Any]]:
        """Each property's overall verdict as JSON-able data, in the shape of ``rasm check
        --format json`` (with counts where ``rasm check`` lists the violations)."""
        return [
            {
                "name": o.name,
                "verdict": o.state,
                "violations": o.violations,
                "judged": o.judged,
                "inconclusive": o.inconclusive,
                "errors": o.errors,
                "first_error": o.first_error,
                "missing": list(o.missing),
                "vacuous": [u.text for u in o.vacuous],
            }
            for o in self.outcomes.values()
        ]


def summarise(
    app: str,
    clock: str,
    duration: float,
    *,
    state: StateManager,
    checker: TrustworthinessChecker | None,
    orchestrator: AdaptationOrchestrator | None,
    telegraf: Telegraf | None,
    trace: TraceWriter,
    bus: dict[str, int],
    missed_iterations: int,
    stopped_by: str | None,
    repeated_failures: dict[str, int],
    fallback: FallbackSwitch | None = None,
    write_failures: list[WriteFailure] | None = None,
    damage: list[Damage] | None = None,
    off: tuple[str, ...] = (),
    calls: dict[str, CallCounts] | None = None,
    role: Role = Role.ALL,
    managed: ManagedSystem | None = None,
) -> RunSummary:
    """The run so far, read from its blocks (nothing is changed). ``checker``,
    ``orchestrator`` and ``telegraf`` are the managing side's (None in a managed-only process:
    no verdicts, no loop counts). ``off``: the platform properties the app turned off."""
    outcomes = dict(checker.outcomes) if checker is not None else {}
    return RunSummary(
        app=app,
        clock=clock,
        duration=duration,
        stats=orchestrator.stats if orchestrator is not None else LoopStats(),
        verdicts={name: o.state for name, o in outcomes.items()},
        violations={name: o.violations for name, o in outcomes.items() if o.violations},
        timing={
            stage: state.percentiles(stage)
            for stage in STAGES
            if orchestrator is not None and state.stage_timing.get(stage)
        },
        records=trace.records,
        rejected_data=dict(telegraf.rejected) if telegraf is not None else {},
        bus=bus,
        missed_iterations=missed_iterations,
        modes=state.get_status(),
        trace=str(trace.path) if trace.path else None,
        stopped_by=stopped_by,
        repeated_failures=repeated_failures,
        outcomes=outcomes,
        fallback_engagements=fallback.engagements if fallback is not None else None,
        write_failures=list(write_failures or ()),
        damage=list(damage or ()),
        off=off,
        calls=dict(calls or {}),
        role=role,
        managed=describe_activity(managed) if managed is not None else [],
    )


def bus_refusals(
    transport: Transport, dist: Distribution, external_refused: int = 0
) -> dict[str, int]:
    """What the bus brought that was refused, by what it was (only the non-zero counts)."""
    updates = dist.updates
    tracker = dist.tracker
    counts = {
        "malformed messages": transport.stats.malformed,
        "actions refused by the effector gate": dist.actions_refused,
        "updates refused": updates.refused if updates is not None else 0,
        "presence messages refused (unsigned, forged or replayed)": (
            tracker.refused if tracker is not None else 0
        ),
        "external verdicts refused (not the source's own)": external_refused,
    }
    return {what: n for what, n in counts.items() if n}
