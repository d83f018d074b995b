"""A building block: a Python object driven through its operation modes by its statechart.

The chart decides which mode the block is in; the block does the work of a mode when the chart
enters it and reports back with a done signal (sismic has no done-events), following the lifecycle
convention of docs/statecharts.md:

    instantiated --configure--> configuration --configuration_done--> initialization
    --initialization_done--> initialized (core task) ; failed -> fault --reset|terminate-->

Subclasses override :meth:`on_configuration`, :meth:`on_initialization`, :meth:`on_termination`
and :meth:`on_fault`; an exception in the first two becomes the ``failed`` event. A sub-state ``s``
of the core task entered by the chart calls ``on_enter_s()`` when the block defines it.

The low-frequency work of a block (an action through Adaptation Manager, Trustworthiness Manager
and Trustworthiness Checker; a persistence batch) steps its chart through the core task's
sub-states. The per-record work (Telegraf digesting, knowledge registration, logging) only asks
the block's mode: a chart step costs tens of microseconds, a record must cost less.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

from sismic.clock import Clock
from sismic.model import MacroStep, Statechart

from rasm.errors import ExecutionError, PlatformError, RasmError
from rasm.logs import RepeatedLogs
from rasm.platform.action_outcome import ActionOutcome
from rasm.platform.components import Action
from rasm.resources import platform_chart
from rasm.statechart import Interpreter, SimulatedClock, load_statechart

__all__ = ["MODES", "Block", "ModeListener", "shared_chart"]

MODES = ("instantiated", "configuration", "initialization", "initialized", "fault", "terminated")
# the modes whose work the block does itself, not through an on_enter_<state> hook
_LIFECYCLE_WORK = frozenset({"configuration", "initialization", "fault", "terminated"})
ModeListener = Callable[["Block", str], object]

_log = logging.getLogger("rasm.platform")
_CHARTS: dict[tuple[str, bytes], Statechart] = {}
_CHARTS_LOCK = threading.Lock()


def shared_chart(name: str | Path) -> Statechart:
    """The chart ``name`` (a platform chart's name, or a YAML file), loaded once per content.

    A loaded chart is never changed by an interpreter, so every block (and every platform built
    in this process) shares it, with the tables the fast interpreter computes for it. The file is
    read each time and parsed again only if its bytes changed (a modification time can stay the
    same across two quick writes).
    """
    path = Path(name) if str(name).endswith((".yaml", ".yml")) else platform_chart(str(name))
    try:
        key = (str(path), path.read_bytes())
    except OSError:  # let the loader report the missing file
        return load_statechart(path)
    with _CHARTS_LOCK:
        if key not in _CHARTS:
            _CHARTS[key] = load_statechart(path)
        return _CHARTS[key]


class Block:
    """Base class of every building block. ``chart_name`` names its chart in ``statecharts/``."""

    chart_name: ClassVar[str] = ""
    short_name: ClassVar[str] = ""

    def __init__(
        self,
        name: str | None = None,
        *,
        depends_on: tuple[Block, ...] = (),
        clock: Clock | None = None,
        chart: str | Path | Statechart | None = None,
        context: dict[str, Any] | None = None,
        logs: RepeatedLogs | None = None,
        on_deadline: Callable[[Block, float], object] | None = None,
    ) -> None:
        self.name = name or self.short_name or type(self).__name__
        # the blocks Core starts before this one (and stops after it)
        self.depends_on = tuple(depends_on)
        statechart = (
            chart if isinstance(chart, Statechart) else shared_chart(chart or self.chart_name)
        )
        self.clock = clock or SimulatedClock()
        self.interpreter = Interpreter(statechart, clock=self.clock, initial_context=context)
        self.failure_reason: str | None = None
        self.step_failures = 0
        self._lock = threading.RLock()
        self._running = False
        self._listeners: list[ModeListener] = []
        self._mode = "instantiated"
        # Called with (block, time) when the chart has a timer due at `time` (after(), idle(),
        # delayed events): the platform's scheduler then steps the chart at that time.
        self.on_deadline = on_deadline
        self._armed: float | None = None
        # failures that recur at every step are logged once, then counted (the platform
        # gives all its blocks one RepeatedLogs)
        self.logs = RepeatedLogs() if logs is None else logs
        # the action a request (:meth:`request`) asks the chart about, and the answer so far
        self.action: Action | None = None
        self._answer = ActionOutcome(False, "")
        self.send(None)  # the initial step: enter `instantiated`

    # ------------------------------------------------------------------ hooks

    def on_configuration(self) -> None:
        """Configure the block (read its parameters). Raise to fail."""

    def on_initialization(self) -> None:
        """Acquire resources and start the core task. Raise to fail."""

    def on_termination(self) -> None:
        """Release resources. Called once, on entering ``terminated``."""

    def on_fault(self, reason: str | None) -> None:
        """Called on entering ``fault``."""

    def on_event_sent(self, name: str, data: dict[str, Any]) -> None:
        """Called for each event the chart sends (``send(...)`` in an action)."""

    # ------------------------------------------------------------------ driving

    @property
    def mode(self) -> str:
        """The block's operation mode: one of :data:`MODES`."""
        return self._mode

    @property
    def configuration(self) -> list[str]:
        return self.interpreter.configuration

    def add_mode_listener(self, listener: ModeListener) -> None:
        """Call ``listener(block, mode)`` whenever the block changes mode."""
        self._listeners.append(listener)

    def post(self, event: str, **data: Any) -> None:
        """Queue an event for the chart without running it (safe from inside a hook)."""
        self.interpreter.queue(event, **data)

    def send(self, event: str | None, **data: Any) -> list[MacroStep]:
        """Queue ``event`` (if any) and run the chart until it is stable, doing each mode's work."""
        with self._lock:
            if event is not None:
                self.interpreter.queue(event, **data)
            if self._running:  # re-entrant call from a hook: the outer loop will run it
                return []
            self._running = True
            try:
                steps = self._run()
            finally:
                self._running = False
            self._arm_timer()
            return steps

    def _arm_timer(self) -> None:
        if self.on_deadline is None:
            return
        due = self.interpreter.next_deadline()
        if due is None:  # the usual case: no timer, and no need to read the clock
            return
        now = self.clock.time
        # The chart just ran until nothing more happened: a deadline not after now is stale
        # (a guard that also waits on something else); waking for it again would spin.
        if due <= now or (self._armed is not None and now < self._armed <= due):
            return
        self._armed = due
        self.on_deadline(self, due)

    def request(self, event: str, action: Action, unanswered: str) -> ActionOutcome:
        """Ask the chart, with ``event``, about ``action`` (its hooks read it as :attr:`action`
        and reply with :meth:`answer`); the reply, or a refusal saying ``unanswered`` when no
        hook replied. A block that is not running refuses without asking: fail closed."""
        if self._mode != "initialized":
            return ActionOutcome(False, f"{self.chart_name.replace('_', ' ')} is {self._mode}")
        self.action = action
        self._answer = ActionOutcome(False, unanswered)
        self.send(event)
        return self._answer

    def answer(self, outcome: ActionOutcome, event: str) -> None:
        """A hook's reply to the request in hand, and the event that tells the chart."""
        self._answer = outcome
        self.post(event)

    def wake(self) -> None:
        """Step the chart now (its timer is due)."""
        self._armed = None
        self.send(None)

    def _run(self) -> list[MacroStep]:
        steps: list[MacroStep] = []
        while True:
            try:
                step = self.interpreter.execute_once()
            except Exception as exc:
                # the interpreter rolled the step back and discarded its event (a monitor that
                # refuses a step, an action that raises): the block stays where it was
                self.step_failures += 1
                # an ExecutionError's message already names what the chart code raised
                why = f"{type(exc).__name__}: {exc}"
                if isinstance(exc, ExecutionError):
                    why = str(exc)
                what = f"{self.name}: step refused and rolled back: {why}"
                self.logs.log(_log, logging.ERROR, what)
                failure = self.interpreter.last_failure
                if failure is None or failure.event is None:
                    return steps  # an eventless step failed: only a new event can help
                continue
            if step is None:
                return steps
            steps.append(step)
            for state in step.entered_states:
                self._entered(state)
            for sent in step.sent_events:
                self.on_event_sent(sent.name, dict(sent.data))

    def _entered(self, state: str) -> None:
        if state in MODES:
            self._mode = state
            for listener in list(self._listeners):
                listener(self, state)
        if state in _LIFECYCLE_WORK:
            self._lifecycle_work(state)
            return
        hook = getattr(self, f"on_enter_{state}", None)
        if hook is not None:
            hook()

    def _lifecycle_work(self, state: str) -> None:
        """The block's own work on entering ``state``, one of :data:`_LIFECYCLE_WORK`."""
        if state == "configuration":
            self._do(self.on_configuration, "configuration_done")
        elif state == "initialization":
            self._do(self.on_initialization, "initialization_done")
        elif state == "fault":
            self.failure_reason = self.interpreter.context.get("failure_reason")
            self.on_fault(self.failure_reason)
        else:  # terminated
            try:
                self.on_termination()
            except Exception:  # shutting down must go on; the failure is logged
                _log.exception("%s: error while terminating", self.name)

    def _do(self, work: Callable[[], None], done: str) -> None:
        try:
            work()
        except RasmError as exc:  # an expected failure (a broker down): its message says it all
            _log.error("%s: %s failed: %s: %s", self.name, work.__name__, type(exc).__name__, exc)
            self.post("failed", reason=f"{type(exc).__name__}: {exc}")
        except Exception as exc:
            _log.exception("%s: %s failed", self.name, work.__name__)
            self.post("failed", reason=f"{type(exc).__name__}: {exc}")
        else:
            self.post(done)

    def require_mode(self, *modes: str) -> None:
        if self._mode not in modes:
            raise PlatformError(f"{self.name} is in mode {self._mode!r}, not {' or '.join(modes)}")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} mode={self._mode}>"
