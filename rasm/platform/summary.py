"""What a run of the loop comes to: the summary ``rasm run`` prints at the end."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rasm.platform.adaptation_orchestrator import LoopStats
from rasm.properties.outcome import PASSING, PropertyOutcome

__all__ = ["RunSummary"]


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

    @property
    def ok(self) -> bool:
        """No property violated, in error or not judged (inconclusive alone passes)."""
        return all(state in PASSING for state in self.verdicts.values())

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
            }
            for o in self.outcomes.values()
        ]
