"""Measuring the demonstrator: one seeded run with or without the adaptation loop, and the
numbers the benchmark and the tests compare (collisions, goal reached, time to goal, latencies).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .world import generate_scenario

__all__ = ["APP", "NoPlan", "Outcome", "outcome_of", "run"]

APP = Path(__file__).resolve().parents[1]


class NoPlan:
    """The loop without its Plan stage: occlusions are found, nothing is done about them."""

    def plan(self, ctx):
        return None


@dataclass
class Outcome:
    """What one run achieved."""

    collisions: int = 0
    reached: bool = False
    time_to_goal: float | None = None
    detection: list[float] = field(default_factory=list)  # debris onset -> anomaly (s)
    detect_to_act: list[float] = field(default_factory=list)  # anomaly -> executed (s)
    loop_compute: list[float] = field(default_factory=list)  # stage time of those iterations (s)
    executed: int = 0


def outcome_of(records: list[tuple[float, dict[str, Any]]]) -> Outcome:
    """Read an :class:`Outcome` off the adaptation trace's ``(time, record)`` pairs."""
    out = Outcome()
    debris, onsets, pending, anomaly_at, compute = 0, [], [], None, 0.0
    for time, r in records:
        if r.get("collision"):
            out.collisions += 1
        if r.get("nav_mode") == "arrived" and not out.reached:
            out.reached, out.time_to_goal = True, time
        if "debris" in r:
            if r["debris"] > debris:
                onsets.append(time)
            debris = r["debris"]
        if r.get("stage") == "monitor":
            compute = 0.0
        compute += float(r.get("duration", 0.0))
        if r.get("anomaly"):
            if onsets:
                pending.extend(time - t for t in onsets)
                onsets = []
            anomaly_at = time
        if r.get("executed"):
            out.executed += 1
            out.detection.extend(pending)
            pending = []
            if anomaly_at is not None:
                out.detect_to_act.append(time - anomaly_at)
                out.loop_compute.append(compute)
                anomaly_at = None
    return out


def run(
    seed: int,
    *,
    loop: bool = True,
    duration: float = 90.0,
    scenario: dict | None = None,
    clock: str = "simulated",
) -> Outcome:
    """Run scenario ``seed`` (:func:`~tb4.world.generate_scenario`, or ``scenario``) with the
    simulator seeded by ``seed``, on the simulated clock unless told otherwise."""
    from rasm import Platform, RunOptions, load_manifest

    platform = Platform(
        load_manifest(APP),
        RunOptions(
            clock=clock,
            seed=seed,
            knowledge="memory",
            scenario=generate_scenario(seed) if scenario is None else scenario,
            components=None if loop else {"plan": NoPlan()},
        ),
    )
    records: list[tuple[float, dict[str, Any]]] = []
    platform.on_record.append(lambda time, record: records.append((time, dict(record))))
    platform.run(duration)
    return outcome_of(records)
