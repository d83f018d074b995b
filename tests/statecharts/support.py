"""Shared helpers for the platform statechart tests: where the charts are, how to drive them.

The charts are loaded and run exactly as the platform loads and runs them (``rasm.statechart``:
validated loading, the atomic interpreter), so these tests check the shipped files, not copies.
Driving a chart always goes through a simulated clock: time advances only when a test says so,
which is what makes the `after(...)` budgets testable without sleeping.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sismic.model import Statechart

from rasm.statechart import Interpreter, SimulatedClock, load_statechart

REPO = Path(__file__).resolve().parents[2]
CHART_DIR = REPO / "statecharts"
MONITOR_DIR = REPO / "monitors"

#: The building blocks of the platform, one chart each.
BLOCKS = (
    "core",
    "adaptation_manager",
    "adaptation_orchestrator",
    "state_manager",
    "logging_and_tracking",
    "trustworthiness_manager",
    "trustworthiness_checker",
    "knowledge_manager",
    "communication_manager",
    "telegraf",
    "storage_manager",
    "fallback",
)
MONITORS = ("accepted_before_executing", "stage_outcome")

MODES = ("instantiated", "configuration", "initialization", "initialized", "fault", "terminated")

#: The lifecycle convention as a reference model: (mode, event) -> next mode. Any event not listed
#: for a mode leaves the mode unchanged.
LIFECYCLE = {
    ("instantiated", "configure"): "configuration",
    ("instantiated", "terminate"): "terminated",
    ("configuration", "configuration_done"): "initialization",
    ("configuration", "failed"): "fault",
    ("configuration", "terminate"): "terminated",
    ("initialization", "initialization_done"): "initialized",
    ("initialization", "failed"): "fault",
    ("initialization", "terminate"): "terminated",
    ("initialized", "failed"): "fault",
    ("initialized", "terminate"): "terminated",
    ("fault", "reset"): "instantiated",
    ("fault", "terminate"): "terminated",
}
LIFECYCLE_EVENTS = sorted({event for _, event in LIFECYCLE})

#: Eventless transitions a chart may take out of `initialized` into `fault` on its own: a budget
#: the block's core task can overrun (chart name -> source sub-states).
TIMED_FAULTS = {"communication_manager": {"reconnecting"}}

STAGES = ("monitoring", "analysing", "planning", "legitimating", "executing")
#: The orchestrator's stage outcome events, per stage state.
OUTCOMES = {
    "idle": ("tick",),
    "monitoring": ("monitored",),
    "analysing": ("anomaly", "no_anomaly"),
    "planning": ("planned", "no_plan"),
    "legitimating": ("accepted", "rejected"),
    "executing": ("executed", "dropped"),
}
LOOP_EVENTS = sorted({e for events in OUTCOMES.values() for e in events} | {"stage_failed"})


def chart_path(name: str) -> Path:
    return CHART_DIR / f"{name}.yaml"


def monitor_path(name: str) -> Path:
    return MONITOR_DIR / f"{name}.yaml"


_CACHE: dict[Path, Statechart] = {}


def load(path: Path) -> Statechart:
    """Load a chart once per test session: the model is immutable, interpreters are not."""
    if path not in _CACHE:
        _CACHE[path] = load_statechart(path)
    return _CACHE[path]


def transition_events(chart: Statechart) -> set[str]:
    """The event names the chart's transitions react to."""
    return {t.event for t in chart.transitions if t.event is not None}


@dataclass
class Run:
    """An interpreter on a simulated clock, with every macro step it took."""

    interpreter: Any
    clock: SimulatedClock
    steps: list = field(default_factory=list)

    def advance(self, seconds: float) -> list:
        """Let simulated time pass, then take the steps that became due (timeouts)."""
        self.clock.time += seconds
        taken = self.interpreter.execute()
        self.steps.extend(taken)
        return taken

    def advance_to(self, time: float) -> list:
        """Set simulated time to exactly ``time`` (no rounding from sums), then step."""
        self.clock.time = time
        taken = self.interpreter.execute()
        self.steps.extend(taken)
        return taken

    def send(self, event: str, **data: Any) -> list:
        """Queue one event and take every step until the chart is stable again."""
        self.interpreter.queue(event, **data)
        taken = self.interpreter.execute()
        self.steps.extend(taken)
        return taken

    def send_all(self, events: Iterable[str]) -> None:
        for event in events:
            self.send(event)

    @property
    def configuration(self) -> list[str]:
        return self.interpreter.configuration

    @property
    def context(self):
        return self.interpreter.context


def start(
    chart: Statechart,
    *,
    context: dict[str, Any] | None = None,
    monitors: Sequence[Statechart] = (),
    engine: type = Interpreter,
) -> Run:
    """A fresh interpreter for ``chart`` (rasm's unless ``engine`` says otherwise: stock sismic's
    ``Interpreter`` has the same API), monitors bound, initial step taken."""
    clock = SimulatedClock()
    interpreter = engine(chart, clock=clock, initial_context=context)
    for monitor in monitors:
        interpreter.bind_property_statechart(monitor)
    run = Run(interpreter, clock)
    run.steps.extend(interpreter.execute())
    return run


BRING_UP = ("configure", "configuration_done", "initialization_done")


def micro_steps(macro_steps: Iterable) -> list:
    return [micro for macro in macro_steps for micro in macro.steps]


def entered(macro_steps: Iterable) -> list[str]:
    """Every state entered, in order, over the given macro steps."""
    return [name for micro in micro_steps(macro_steps) for name in micro.entered_states]


def sent(macro_steps: Iterable) -> list[str]:
    """The names of the events the chart sent over the given macro steps."""
    return [event.name for micro in micro_steps(macro_steps) for event in micro.sent_events]
