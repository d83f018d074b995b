"""Run a chart live: steps happen when an event arrives or a timer is due, never by polling.

The runner sleeps on a condition variable until either :meth:`ChartRunner.send` queues an event or
the interpreter's :meth:`~rasm.statechart.interpreter.Interpreter.next_deadline` is reached, so an
idle chart costs no CPU: the runner never polls.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from sismic.model import MacroStep

from rasm.statechart.interpreter import Interpreter

__all__ = ["ChartRunner"]


class ChartRunner:
    """Drives one :class:`Interpreter` on its (monotonic) clock from a thread of its own.

    ``on_step`` is called with every macro step, from the runner's thread; ``on_error`` with every
    exception raised by a step (the step has been rolled back; the runner goes on).
    """

    def __init__(
        self,
        interpreter: Interpreter,
        *,
        on_step: Callable[[MacroStep], Any] | None = None,
        on_error: Callable[[BaseException], Any] | None = None,
    ) -> None:
        self.interpreter = interpreter
        self.on_step = on_step
        self.on_error = on_error
        self._wake = threading.Condition()
        self._inbox: list[tuple[str, dict[str, Any]]] = []
        self._stopping = False
        self._thread: threading.Thread | None = None
        self.steps = 0
        self.wakeups = 0  # passes of the loop: stays put while the chart has nothing to do
        self.errors: list[BaseException] = []
        self._sleeping_forever = False  # asleep with no timeout: only an event can wake it

    def send(self, name: str, **data: Any) -> None:
        """Queue an external event (from any thread) and wake the runner."""
        with self._wake:
            self._inbox.append((name, data))
            self._wake.notify_all()

    def start(self) -> ChartRunner:
        self._thread = threading.Thread(target=self.run, name="chart-runner", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float | None = 5.0) -> None:
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)

    def wait_until_idle(self, timeout: float | None = None, *, after_wakeups: int = 0) -> bool:
        """Block until the runner sleeps with nothing queued and no timer pending (and has made
        more than ``after_wakeups`` passes); False on timeout."""
        with self._wake:
            return self._wake.wait_for(
                lambda: self._sleeping_forever and not self._inbox
                and self.wakeups > after_wakeups,
                timeout,
            )

    def run(self) -> None:
        """The loop: take queued events, execute until stable, sleep until the next deadline."""
        interp = self.interpreter
        while True:
            with self._wake:
                self.wakeups += 1
                if self._stopping:
                    return
                inbox, self._inbox = self._inbox, []
            for name, data in inbox:
                interp.queue(name, **data)
            stalled = self._execute()
            if interp.final:
                return
            with self._wake:
                if self._inbox or self._stopping:
                    continue
                deadline = None if stalled else interp.next_deadline()
                timeout = None if deadline is None else max(deadline - interp.clock.time, 0.0)
                if timeout != 0.0:
                    self._sleeping_forever = timeout is None
                    self._wake.notify_all()  # for wait_until_idle
                    self._wake.wait(timeout)
                    self._sleeping_forever = False

    def _execute(self) -> bool:
        """Execute until stable; True when an eventless step failed (only an event can help)."""
        interp = self.interpreter
        while True:
            try:
                step = interp.execute_once()
            except Exception as exc:  # rolled back by the interpreter; report and go on
                self.errors.append(exc)
                if self.on_error is not None:
                    self.on_error(exc)
                failure = interp.last_failure
                if failure is None or failure.event is None:
                    return True
                continue
            if step is None:
                return False
            self.steps += 1
            if self.on_step is not None:
                self.on_step(step)
