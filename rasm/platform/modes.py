"""The managed system's operation modes as a statechart (``managed_system.modes`` in app.yaml).

The app models its managed system with a sismic chart; the chart's active states are the managed
system's modes. Each batch of values the platform stores in knowledge (a digested probe message,
the Monitor's derived signals) reaches the chart as one ``record`` event whose data are those
values; the chart's code reads them as ``event.data`` (``event.data.get('nav_mode')``) and the
whole knowledge, read-only, as ``knowledge`` (``knowledge.get('velocity', 0.0)``). Timers
(``after(2.0)``) measure the platform's clock: the platform steps the chart when one is due,
records or not.

An effector's ``modes:`` name states of this chart: the Trustworthiness Checker sends its actions
only while one of them is active. Each change of the active states goes in the trace as ``mode``
(the active leaf states, comma-separated) and ``mode_<state>`` (true for a state just entered,
false for one just left; the first record has every state), so properties read the modes like
any signal (``in_mode("docking")`` reads ``mode_docking``).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sismic.model import Event, Statechart

from rasm.errors import ExecutionError
from rasm.platform.action_outcome import Emit
from rasm.statechart import Clock, Interpreter, SimulatedClock, load_statechart

if TYPE_CHECKING:
    from rasm.knowledge.base import KnowledgeBase

__all__ = ["KnowledgeView", "ManagedSystemModes", "ModesRunner", "mode_signals"]

_log = logging.getLogger("rasm.modes")
_SCALARS = (int, float, bool, str)


class KnowledgeView(Mapping[str, Any]):
    """The knowledge as a chart reads it: the latest value of each key, never writable (a list
    or dict value is a copy, so chart code cannot change what the platform stored)."""

    def __init__(self, knowledge: KnowledgeBase) -> None:
        self._knowledge = knowledge

    def __getitem__(self, key: str) -> Any:
        sample = self._knowledge.read_sample(key)
        if sample is None:
            raise KeyError(key)
        value = sample.value
        return value if isinstance(value, _SCALARS) or value is None else copy.deepcopy(value)

    def __iter__(self) -> Iterator[str]:
        return iter(self._knowledge.keys())

    def __len__(self) -> int:
        return len(self._knowledge.keys())

    def __repr__(self) -> str:
        return f"<knowledge, {len(self)} keys>"

    def __deepcopy__(self, memo: dict[int, Any]) -> KnowledgeView:
        # a step's snapshot copies the chart's context: a view has nothing of its own to copy
        return self


def mode_signals(chart: Statechart) -> dict[str, str]:
    """The trace keys a modes chart writes, with their types: ``mode`` and ``mode_<state>``."""
    signals = {"mode": "str"}
    for state in chart.states:
        if state != chart.root:
            signals[f"mode_{state}"] = "bool"
    return signals


class ManagedSystemModes:
    """Runs the app's modes chart over the values stored in knowledge.

    ``observe(time, values)`` steps it and returns the trace record of the change, if the
    active states changed. The chart has a clock of its own set to each record's time, so it
    behaves the same on the simulated and the wall clock.
    """

    def __init__(self, chart: str | Path | Statechart, knowledge: KnowledgeBase) -> None:
        self.chart = chart if isinstance(chart, Statechart) else load_statechart(chart)
        self.clock = SimulatedClock()
        self.interpreter = Interpreter(
            self.chart, clock=self.clock, initial_context={"knowledge": KnowledgeView(knowledge)}
        )
        self.failures = 0
        # the last record's step failed: the chart's modes may be stale, so none is vouched for
        self.failing = False
        self._active: frozenset[str] = frozenset()

    @property
    def active(self) -> frozenset[str]:
        """Every active state of the chart but its root (leaf states and their ancestors)."""
        return frozenset(self.interpreter.configuration) - {self.chart.root}

    @property
    def leaves(self) -> list[str]:
        """The active leaf states, in the chart's order: the managed system's modes now."""
        active = self.active
        return [
            name
            for name in self.chart.states
            if name in active and not any(c in active for c in self.chart.children_for(name))
        ]

    def start(self, time: float) -> dict[str, Any]:
        """Enter the initial states; the trace record of the initial modes (``mode_<state>``
        for every state, so that each has a value from the start)."""
        self.clock.time = max(self.clock.time, time)
        self._run()
        record = self._change() or {"mode": ",".join(self.leaves)}
        for state in self.chart.states:
            if state != self.chart.root:
                record.setdefault(f"mode_{state}", False)
        return record

    def observe(self, time: float, values: Mapping[str, Any]) -> dict[str, Any] | None:
        """One ``record`` event with ``values``; the trace record of the mode change, or None."""
        self.clock.time = max(self.clock.time, time)
        event = Event("record")
        event.data = dict(values)  # set directly: a signal may be called `name` or `data`
        self.interpreter.queue(event)
        self._run()
        return self._change()

    def wake(self, time: float) -> dict[str, Any] | None:
        """Step the chart at ``time`` with no record (a timer of its is due); the trace record
        of the mode change, or None."""
        self.clock.time = max(self.clock.time, time)
        self._run()  # a timer holds at the deadline it reported (rasm.statechart.timers)
        return self._change()

    def next_deadline(self) -> float | None:
        """When a timer of the chart (``after(...)``) is next due, if after its clock's now."""
        due = self.interpreter.next_deadline()
        return due if due is not None and due > self.clock.time else None

    def _run(self) -> None:
        self.failing = False
        while True:
            try:
                if self.interpreter.execute_once() is None:
                    return
            except ExecutionError as exc:
                # the step is rolled back and its event dropped: the chart may have missed a
                # change of mode, so until a record goes through no mode is vouched for
                self.failing = True
                self.failures += 1
                if self.failures == 1:
                    _log.error("the modes chart %s refused a step: %s", self.chart.name, exc)
                failure = self.interpreter.last_failure
                if failure is None or failure.event is None:
                    return

    def _change(self) -> dict[str, Any] | None:
        active = self.active
        if active == self._active:
            return None
        entered, left = active - self._active, self._active - active
        self._active = active
        record: dict[str, Any] = {"mode": ",".join(self.leaves)}
        record.update({f"mode_{s}": True for s in sorted(entered)})
        record.update({f"mode_{s}": False for s in sorted(left)})
        return record


class ModesRunner:
    """The modes chart in the loop: knowledge's ``mode`` and the trace follow its active states,
    and the chart is stepped whenever a timer of its is due, records or not.

    ``register_values(values, time)`` stores ``mode`` in knowledge (returning what it refused,
    which goes to ``refused(key, value, exc)``); ``emit(time, record)`` writes a trace record;
    ``at(time, job)`` has the loop run ``job`` at ``time`` on ``clock``.
    """

    def __init__(
        self,
        modes: ManagedSystemModes,
        *,
        register_values: Callable[[dict[str, Any], float], Mapping[str, Exception]],
        refused: Callable[[str, object, Exception], object],
        emit: Emit,
        at: Callable[[float, Callable[[], object]], object],
        clock: Clock,
    ) -> None:
        self.modes = modes
        self.register_values = register_values
        self.refused = refused
        self.emit = emit
        self.at = at
        self.clock = clock
        self._armed: float | None = None  # when the chart's next timer job runs

    @property
    def mode(self) -> frozenset[str] | None:
        """The managed system's modes now: the chart's active states, or None while its last
        step failed (no mode is vouched for)."""
        return None if self.modes.failing else self.modes.active

    def start(self, time: float) -> None:
        """Enter the initial modes: in knowledge and in a trace record of their own."""
        initial = self.modes.start(time)
        self._changed(time, initial)
        self.emit(time, initial)
        self._arm()

    def observe(self, time: float, values: Mapping[str, Any]) -> dict[str, Any] | None:
        """Step the chart with a batch of values stored; the mode change they caused (for their
        trace record), or None."""
        change = self.modes.observe(time, values)
        if change:
            self._changed(time, change)
        self._arm()
        return change

    def _arm(self) -> None:
        """Have the loop step the chart when its next timer is due (once per deadline: a record
        arriving first leaves the job to find nothing to do)."""
        due = self.modes.next_deadline()
        if due is not None and due != self._armed:
            self._armed = due
            self.at(due, self._wake)

    def _wake(self) -> None:
        self._armed = None
        time = self.clock.time
        change = self.modes.wake(time)
        if change:
            self._changed(time, change)
            self.emit(time, change)
        self._arm()

    def _changed(self, time: float, change: dict[str, Any]) -> None:
        """``mode`` in knowledge says which modes are active now, for the stages and rules."""
        refused = self.register_values({"mode": change["mode"]}, time)
        for key, exc in refused.items():
            self.refused(key, change["mode"], exc)
