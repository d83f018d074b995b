"""The loop's time: the scheduler's now() is its clock's time."""

from __future__ import annotations

import math

import pytest
import sismic.clock.clock as sismic_clock
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock

from rasm.platform.scheduler import Scheduler
from rasm.statechart import MonotonicClock

SETTINGS = settings(max_examples=400, deadline=None, database=None)


def _same(a, b) -> bool:
    """The same value of the same type, the sign of a zero and a nan included."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        if math.isnan(a):
            return math.isnan(b)
        return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
    return a == b


# -------------------------------------------------------------------- Scheduler.now

CLOCK_OPS = st.lists(
    st.one_of(
        st.tuples(st.just("set"), st.sampled_from([-0.0, 0.0, 1, 2.5]) | st.floats(-1, 50)),
        st.tuples(st.just("wall"), st.floats(0, 5)),  # the wall clock moves on
        st.tuples(st.just("speed"), st.floats(0.25, 4)),
        st.tuples(st.sampled_from(["start", "stop"]), st.none()),
    ),
    max_size=20,
)


@SETTINGS
@given(CLOCK_OPS)
def test_the_schedulers_now_is_the_clocks_time(ops):
    wall = [1000.0]
    with pytest.MonkeyPatch.context() as patch:  # a running clock reads this wall clock
        patch.setattr(sismic_clock, "time", lambda: wall[0])
        clock = SimulatedClock()
        jobs = Scheduler(clock)
        for op, arg in ops:
            if op == "wall":
                wall[0] += arg
            elif op == "set":
                if not arg < clock.time:  # (sismic refuses to go back)
                    clock.time = arg
            elif op == "speed":
                clock.speed = arg
            else:
                getattr(clock, op)()
            assert _same(jobs.now(), clock.time)


class _OwnClock(SimulatedClock):
    """A clock of another class: now() asks it."""

    @property
    def time(self) -> float:
        return 42.0


@pytest.mark.parametrize("clock", [_OwnClock(), MonotonicClock(running=False)])
def test_the_schedulers_now_asks_any_other_clock(clock):
    assert _same(Scheduler(clock).now(), clock.time)


# -------------------------------------------------------------------- periodic turns


class _Watched(Scheduler):
    """A scheduler with its own at(): it sees every job scheduled, the periodic turns too."""

    def __init__(self, clock) -> None:
        super().__init__(clock)
        self.seen: list[float] = []

    def at(self, time, job) -> None:
        self.seen.append(time)
        super().at(time, job)


@pytest.mark.parametrize("own", ["subclass", "instance", "none"])
def test_the_turns_of_a_periodic_job_go_through_the_schedulers_own_at(own):
    clock = SimulatedClock()
    jobs = _Watched(clock) if own == "subclass" else Scheduler(clock)
    seen: list[float] = []
    if own == "instance":
        plain_at = jobs.at
        jobs.at = lambda time, job: (seen.append(time), plain_at(time, job))
    ran: list[float] = []
    jobs.every(0.5, lambda: ran.append(clock.time), start=0.0)
    jobs.run_until(2.0)
    assert ran == [0.0, 0.5, 1.0, 1.5, 2.0]
    # the first turn and every next one, the one after the end included
    expected = [] if own == "none" else [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
    assert (jobs.seen if own == "subclass" else seen) == expected
