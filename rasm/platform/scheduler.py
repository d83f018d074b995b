"""The loop's scheduler: timed jobs on one thread, on a simulated or a monotonic clock.

Everything the loop does (stepping the managed-system simulator, orchestrator ticks, statechart
timers, messages arriving from other threads) becomes a job run by one thread, in time order, so a
simulated run with a seed is deterministic. On the simulated clock the scheduler jumps from job to
job as fast as the machine allows; on the wall clock it sleeps on its inbox until the next job
is due or another thread submits one: it never polls.

Jobs from other threads go into the inbox, a queue that takes a job without a lock of the
loop's and wakes the loop only when it sleeps; the loop takes every job waiting at once. At a
transport's rates the two threads thus meet once per batch of messages, not once per message.

A simulated run over a network transport also waits, before each look at the next job, for the
messages it published to come back (:attr:`Scheduler.settle`): their jobs are then in the inbox
before the clock can move past them, just as the in-process bus delivers them at once.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Callable
from functools import partial
from heapq import heappop, heappush
from queue import Empty, SimpleQueue
from typing import Any

from sismic.clock import Clock, SimulatedClock

from rasm.times import format_seconds

__all__ = ["Scheduler"]

Job = Callable[[], Any]


class Scheduler:
    """Runs jobs at their times. ``clock`` is a ``SimulatedClock`` (jumps) or a real clock."""

    def __init__(
        self, clock: Clock, *, on_error: Callable[[BaseException], Any] | None = None
    ) -> None:
        self.clock = clock
        self.simulated = isinstance(clock, SimulatedClock)
        self._heap: list[tuple[float, int, Job]] = []
        self._order = itertools.count()
        self._inbox: SimpleQueue[Job] = SimpleQueue()  # submitted by any thread
        # taken from the inbox by the loop, not yet run (the job that woke a loop asked to stop)
        self._taken: deque[Job] = deque()
        self._stopping = False
        self.on_error = on_error
        self.missed = 0  # turns of periodic jobs skipped because they were already past
        # on the simulated clock: returns once every message on its way to this process's
        # subscriptions has been delivered (their jobs submitted); raises if one never comes
        self.settle: Callable[[], Any] | None = None

    @property
    def time(self) -> float:
        return self.clock.time

    def now(self) -> float:
        """The clock's time."""
        return self.clock.time

    def at(self, time: float, job: Job) -> None:
        """Run ``job`` at ``time`` (loop thread only; other threads use :meth:`submit`)."""
        heappush(self._heap, (time, next(self._order), job))

    def after(self, delay: float, job: Job) -> None:
        self.at(self.clock.time + max(delay, 0.0), job)

    def every(
        self, period: float, job: Job, *, start: float | None = None, skip_missed: bool = False
    ) -> None:
        """Run ``job`` every ``period`` seconds from ``start`` (default: now), drift-free.

        With ``skip_missed``, on the wall clock, turns already past when the job returns (it, or
        another job, overran) are skipped, not run back to back, and counted in :attr:`missed`:
        a control loop catches up with the present instead of bursting through the iterations it
        missed. Without it every turn runs (a simulator integrating time needs them all).
        """
        if period <= 0:
            raise ValueError("period must be positive")
        first = self.clock.time if start is None else start
        if first + period <= first:  # the job would run forever at one instant
            raise ValueError(
                f"a period of {format_seconds(period)} s is too short to move the clock at "
                f"{format_seconds(first)} s"
            )

        def tick(n: int = 0) -> None:
            try:
                job()
            finally:  # a job that raises (reported by on_error) keeps its next turn
                turn = n + 1
                if skip_missed and not self.simulated:
                    current = math.ceil((self.clock.time - first) / period)
                    if current > turn:
                        self.missed += current - turn
                        turn = current
                self.at(first + turn * period, partial(tick, turn))

        self.at(first, tick)

    def submit(self, job: Job) -> None:
        """Run ``job`` on the loop thread as soon as possible, after the jobs submitted before
        it (thread-safe; never blocks)."""
        self._inbox.put(job)

    def stop(self) -> None:
        """Make :meth:`run_until` return after the current job (thread-safe)."""
        self._stopping = True
        # a loop asleep on its inbox looks at the flag (put() is safe in a signal handler)
        self._inbox.put(_wake_up)

    def _take_inbox(self) -> bool:
        """Move every job waiting in the inbox to the loop's own queue; False if none was.
        (Only the loop thread takes from the inbox: a job it sees there stays there.)"""
        took = False
        while not self._inbox.empty():
            self._taken.append(self._inbox.get_nowait())
            took = True
        return took

    def _run_taken(self) -> None:
        """Run the jobs taken from the inbox, in order (a stop asked for by one of them takes
        effect after them all, as at the end of any other job)."""
        while self._taken:
            self._run(self._taken.popleft())

    def _run(self, job: Job) -> None:
        try:
            job()
        except Exception as exc:  # a failing job never stops the loop
            if self.on_error is None:
                raise
            self.on_error(exc)

    def run_until(self, end: float | None) -> None:
        """Run jobs until the clock reaches ``end`` (None: until :meth:`stop`)."""
        clock, heap, simulated = self.clock, self._heap, self.simulated
        while True:
            if self._stopping:
                self._stopping = False
                return
            if self._taken or self._take_inbox():
                self._run_taken()
                continue
            if simulated and self.settle is not None:
                self.settle()  # a message still on the network would be served too late
                if self._take_inbox():
                    continue
            due = heap[0][0] if heap else None
            if end is not None and (due is None or due > end):
                if simulated:
                    clock.time = max(clock.time, end)
                    return
                due = end
            if simulated:
                if due is None:
                    return  # nothing will ever happen again
                clock.time = max(clock.time, due)
                now = clock.time
            else:
                wait = None if due is None else due - clock.time
                if wait is None or wait > 0:
                    # asleep until the next job is due, unless a job is submitted first
                    try:
                        self._taken.append(self._inbox.get(timeout=wait))
                    except Empty:
                        pass
                    else:
                        continue
                if end is not None and clock.time >= end and (not heap or heap[0][0] > end):
                    return
                now = clock.time
            # the jobs due now, then back to the checks above: on the wall clock a loop that
            # has fallen behind (a stage overrunning every period) would otherwise catch up for
            # ever, never reaching ``end`` nor the messages in the inbox
            while heap and heap[0][0] <= now:
                self._run(heappop(heap)[2])
            if not simulated and end is not None and clock.time >= end:
                return


def _wake_up() -> None:
    """The job :meth:`Scheduler.stop` submits: it only wakes the loop."""
