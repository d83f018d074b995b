"""Running user stage code with a time budget, on a worker thread the loop can walk away from.

Python cannot kill a thread, so a stage that overruns its budget is *abandoned*: its result, if it
ever comes, is thrown away, and the next stage runs on a fresh worker. The loop thread never waits
longer than the budget. On a simulated clock an overrun costs exactly the budget in simulated time,
so the orchestrator chart's ``after(stage_budget)`` timer fires as it would live.
"""

from __future__ import annotations

import queue
import threading
import traceback
from collections.abc import Callable
from time import perf_counter
from typing import Any, NamedTuple

from rasm.errors import is_interrupt

__all__ = ["StageOutcome", "StageRunner"]


class StageOutcome(NamedTuple):
    """How a stage call ended: ``ok`` with a ``result``, an ``error`` (with traceback), or
    ``timed_out``. ``duration`` is wall-clock seconds."""

    ok: bool
    result: Any = None
    error: BaseException | None = None
    traceback: str = ""
    timed_out: bool = False
    duration: float = 0.0


class _Worker:
    def __init__(self) -> None:
        self.jobs: queue.SimpleQueue[
            tuple[Callable[..., Any], tuple[Any, ...], queue.SimpleQueue] | None
        ] = queue.SimpleQueue()
        self.thread = threading.Thread(target=self._run, name="rasm-stage", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while True:
            item = self.jobs.get()
            if item is None:
                return
            job, args, reply = item
            start = perf_counter()
            try:
                result = job(*args)
            except BaseException as exc:  # noqa: BLE001 - user code may raise anything
                reply.put(
                    StageOutcome(
                        False,
                        error=exc,
                        traceback=traceback.format_exc(),
                        duration=perf_counter() - start,
                    )
                )
            else:
                reply.put(StageOutcome(True, result, duration=perf_counter() - start))


class StageRunner:
    """Calls stage functions on a worker thread with a timeout (``isolate=False``: inline)."""

    def __init__(self, *, isolate: bool = True) -> None:
        self.isolate = isolate
        self._worker: _Worker | None = None
        self.abandoned = 0

    def call(self, job: Callable[..., Any], budget: float, *args: Any) -> StageOutcome:
        """``job(*args)`` within ``budget`` seconds."""
        if not self.isolate:
            start = perf_counter()
            try:
                result = job(*args)
            except BaseException as exc:  # sys.exit(), raise KeyboardInterrupt: fail the stage
                if is_interrupt(exc):
                    raise
                return StageOutcome(
                    False,
                    error=exc,
                    traceback=traceback.format_exc(),
                    duration=perf_counter() - start,
                )
            duration = perf_counter() - start
            if duration > budget:
                return StageOutcome(False, timed_out=True, duration=duration)
            return StageOutcome(True, result, duration=duration)
        if self._worker is None:
            self._worker = _Worker()
        reply: queue.SimpleQueue[StageOutcome] = queue.SimpleQueue()
        start = perf_counter()
        self._worker.jobs.put((job, args, reply))
        try:
            outcome = reply.get(timeout=budget)
        except queue.Empty:
            # Abandon the stuck worker (it exits after its job); the next call gets a new one.
            self._worker.jobs.put(None)
            self._worker = None
            self.abandoned += 1
            return StageOutcome(False, timed_out=True, duration=perf_counter() - start)
        if outcome.ok and outcome.duration > budget:
            return StageOutcome(False, timed_out=True, duration=outcome.duration)
        return outcome

    def close(self) -> None:
        if self._worker is not None:
            self._worker.jobs.put(None)
            self._worker = None
