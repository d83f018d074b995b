"""Measuring the demonstrator: one seeded run with or without the adaptation loop, and the
numbers the benchmark and the tests compare (collisions, goal reached, time to goal, latencies,
the properties that did not hold, and when the loop first looked for clearance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .world import generate_scenario

__all__ = ["APP", "LOOKS", "NoPlan", "Outcome", "analyse_stage", "outcome_of", "run"]

APP = Path(__file__).resolve().parents[1]

# when the Analyse chart has the robot look for clearance: the chart's variables for each way
LOOKS = {
    # as shipped: keeps_clearance's robustness, now or 0.5 s ahead, below 0.3 m
    "predictive": {},
    # only once keeps_clearance is violated (its robustness now below 0)
    "boolean": {"margin": 0.0, "lookahead": False},
    # never: the loop looks only when the occlusion or the plan's stop_every says so
    "off": {"margin": -math.inf, "lookahead": False},
}
LOOK_REASON = "seen free ahead"  # in the explanation of a look for clearance


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
    failed: list[str] = field(default_factory=list)  # the properties not satisfied
    looks: list[float] = field(default_factory=list)  # times of the looks for clearance (s)
    least_robustness: float | None = None  # of keeps_clearance while the robot drives (m)


def outcome_of(records: list[tuple[float, dict[str, Any]]]) -> Outcome:
    """Read an :class:`Outcome` off the adaptation trace's ``(time, record)`` pairs."""
    out = Outcome()
    debris, onsets, pending, anomaly_at, compute, speed = 0, [], [], None, 0.0, 0.0
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
        speed = r.get("velocity", speed)
        if speed > 0.02 and "robustness_keeps_clearance" in r:
            value = r["robustness_keeps_clearance"]
            if out.least_robustness is None or value < out.least_robustness:
                out.least_robustness = value
        if r.get("anomaly") and LOOK_REASON in str(r.get("explanation", "")):
            out.looks.append(time)
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


def analyse_stage(look: str = "predictive"):
    """The Analyse chart as a stage, looking for clearance the way ``look`` (a key of
    :data:`LOOKS`) says."""
    from rasm.platform import ChartStage

    stage = ChartStage(APP / "statecharts" / "analyse.yaml", "analyse")
    stage.interpreter.context.update(LOOKS[look])  # the chart's preamble keeps preset values
    return stage


def run(
    seed: int,
    *,
    loop: bool = True,
    look: str = "predictive",
    duration: float = 90.0,
    scenario: dict | None = None,
    clock: str = "simulated",
) -> Outcome:
    """Run scenario ``seed`` (:func:`~tb4.world.generate_scenario`, or ``scenario``) with the
    simulator seeded by ``seed``, on the simulated clock unless told otherwise; ``look`` says
    when the loop has the robot look for clearance (:data:`LOOKS`)."""
    from rasm import Platform, RunOptions, load_manifest

    components: dict[str, Any] = {} if loop else {"plan": NoPlan()}
    if look != "predictive":
        components["analyse"] = analyse_stage(look)
    platform = Platform(
        load_manifest(APP),
        RunOptions(
            clock=clock,
            seed=seed,
            knowledge="memory",
            scenario=generate_scenario(seed) if scenario is None else scenario,
            components=components or None,
        ),
    )
    records: list[tuple[float, dict[str, Any]]] = []
    platform.on_record.append(lambda time, record: records.append((time, dict(record))))
    summary = platform.run(duration)
    out = outcome_of(records)
    out.failed = sorted(name for name, v in summary.verdicts.items() if v != "satisfied")
    return out
