"""The loop's scheduler: jobs in time order, drift-free periods, cross-thread submission, and
its turn order: the jobs due now first, then the inbox, then the clock moves on."""

from __future__ import annotations

import threading
import time
from functools import partial

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock

from rasm.platform.scheduler import Scheduler
from rasm.statechart import MonotonicClock


@given(st.lists(st.floats(0, 100, allow_nan=False), max_size=30))
def test_simulated_jobs_run_in_time_order_at_their_time(times):
    scheduler = Scheduler(SimulatedClock())
    ran: list[tuple[float, float]] = []
    for t in times:
        scheduler.at(t, lambda t=t: ran.append((t, scheduler.time)))
    scheduler.run_until(100.0)
    assert [t for t, _ in ran] == sorted(times)
    assert all(at == t for t, at in ran)
    assert scheduler.time == 100.0


def test_a_periodic_job_does_not_drift():
    scheduler = Scheduler(SimulatedClock())
    ran: list[float] = []
    scheduler.every(0.1, lambda: ran.append(scheduler.time), start=0.0)
    scheduler.run_until(100.0)
    assert len(ran) == 1001
    # each time is start + n * period, not an accumulated sum of periods
    assert all(t == n * 0.1 for n, t in enumerate(ran))


@pytest.mark.parametrize("period", [0.0, -1.0, 1e-300])
def test_a_period_that_cannot_move_the_clock_is_refused(period):
    clock = SimulatedClock()
    clock.time = 0.1
    with pytest.raises(ValueError):
        Scheduler(clock).every(period, lambda: None)


def test_a_failing_job_is_reported_and_the_loop_goes_on():
    scheduler = Scheduler(SimulatedClock())
    errors: list[BaseException] = []
    scheduler.on_error = errors.append
    ran: list[str] = []
    scheduler.at(1.0, lambda: 1 / 0)
    scheduler.at(2.0, lambda: ran.append("after"))
    scheduler.run_until(3.0)
    assert [type(e) for e in errors] == [ZeroDivisionError] and ran == ["after"]


def test_a_job_submitted_from_another_thread_wakes_a_sleeping_wall_clock_loop():
    clock = MonotonicClock()
    scheduler = Scheduler(clock)
    done = threading.Event()

    def from_outside() -> None:
        done.set()
        scheduler.stop()

    # nothing is due for 5 s: only the submitted job, run at once, can end this run early (a
    # loop that slept through the submission would run it at 5 s)
    scheduler.at(5.0, lambda: None)
    sender = threading.Thread(target=lambda: scheduler.submit(from_outside))
    sender.start()
    scheduler.run_until(5.0)
    sender.join()
    assert done.is_set() and clock.time < 4


def test_a_wall_clock_loop_behind_its_period_still_ends_and_serves_its_inbox():
    # a job that always takes longer than its period (a stage overrunning every iteration) used
    # to keep the loop catching up for ever: run_until never returned, messages were never served
    clock = MonotonicClock()
    scheduler = Scheduler(clock)
    served: list[float] = []

    def slow() -> None:
        threading.Event().wait(0.03)  # stands for a stage that overruns: 3 periods of work
        scheduler.submit(lambda: served.append(clock.time))

    scheduler.every(0.01, slow, start=clock.time)
    runner = threading.Thread(target=scheduler.run_until, args=(clock.time + 0.3,), daemon=True)
    runner.start()
    runner.join(timeout=10)
    assert not runner.is_alive(), "run_until never returned"
    assert served, "the inbox was never served while the loop was behind"


def test_a_periodic_job_that_raises_keeps_its_next_turns():
    # the next turn was scheduled after the job returned: one exception stopped the loop for good
    scheduler = Scheduler(SimulatedClock())
    errors: list[BaseException] = []
    scheduler.on_error = errors.append
    ran: list[float] = []

    def job() -> None:
        ran.append(scheduler.time)
        raise RuntimeError("a platform bug")

    scheduler.every(1.0, job, start=0.0)
    scheduler.run_until(3.0)
    assert ran == [0.0, 1.0, 2.0, 3.0] and len(errors) == 4


def test_a_wall_clock_loop_that_stalled_skips_the_turns_it_missed():
    # one turn takes ten periods (a stalled stage); the turns that passed meanwhile are skipped,
    # not run back to back: about 1 + 10 runs in 0.2 s instead of the 20 slots
    clock = MonotonicClock()
    scheduler = Scheduler(clock)
    runs: list[float] = []

    def job() -> None:
        runs.append(clock.time)
        if len(runs) == 1:
            time.sleep(0.1)  # the workload: a turn that overruns, not a synchronisation

    scheduler.every(0.01, job, start=0.0, skip_missed=True)
    scheduler.run_until(0.2)
    assert scheduler.missed >= 8
    assert len(runs) <= 13


def test_submitted_jobs_run_after_the_jobs_due_now_and_before_the_clock_moves():
    scheduler = Scheduler(SimulatedClock())
    ran: list[tuple[str, float]] = []

    def note(name: str) -> None:
        ran.append((name, scheduler.time))

    def first() -> None:
        note("first")
        scheduler.submit(lambda: note("submitted"))
        scheduler.submit(lambda: scheduler.submit(lambda: note("submitted by submitted")))

    scheduler.at(1.0, first)
    scheduler.at(1.0, lambda: note("also due"))
    scheduler.at(2.0, lambda: note("later"))
    scheduler.run_until(3.0)
    assert ran == [
        ("first", 1.0),
        ("also due", 1.0),
        ("submitted", 1.0),
        ("submitted by submitted", 1.0),
        ("later", 2.0),
    ]
    assert scheduler.time == 3.0


def test_stop_from_a_job_ends_the_run_before_the_inbox_and_a_second_run_serves_it():
    scheduler = Scheduler(SimulatedClock())
    ran: list[str] = []

    def stopper() -> None:
        scheduler.submit(lambda: ran.append("inbox"))
        scheduler.stop()

    scheduler.at(1.0, stopper)
    scheduler.at(2.0, lambda: ran.append("later"))
    scheduler.run_until(5.0)
    assert ran == [] and scheduler.time == 1.0
    scheduler.run_until(5.0)
    assert ran == ["inbox", "later"] and scheduler.time == 5.0


def test_periodic_turns_interleave_in_time_then_scheduling_order():
    # at 0.5 and 1.0 "slow" goes first: its turn was scheduled before "fast" scheduled its own
    scheduler = Scheduler(SimulatedClock())
    ran: list[tuple[str, float]] = []
    scheduler.every(0.25, lambda: ran.append(("fast", scheduler.time)))
    scheduler.every(0.5, lambda: ran.append(("slow", scheduler.time)), start=0.5, skip_missed=True)
    scheduler.run_until(1.0)
    assert ran == [
        ("fast", 0.0),
        ("fast", 0.25),
        ("slow", 0.5),
        ("fast", 0.5),
        ("fast", 0.75),
        ("slow", 1.0),
        ("fast", 1.0),
    ]


def _journey(clock: SimulatedClock) -> list[tuple[str, float]]:
    scheduler = Scheduler(clock)
    seen: list[tuple[str, float]] = []

    def note(name: str) -> None:
        seen.append((name, clock.time))

    def overrun() -> None:  # a stage overrun moves the simulated clock itself
        note("overrun")
        clock.time = clock.time + 0.7

    def play() -> None:  # a running clock (standing still at speed 0) takes the property path
        clock.speed = 0
        clock.start()
        note("play")

    def pause() -> None:
        clock.stop()
        note("pause")

    scheduler.every(0.25, lambda: note("tick"))
    scheduler.at(0.5, overrun)
    scheduler.at(1.0, lambda: note("already past"))
    scheduler.at(1.5, play)
    scheduler.at(2.0, lambda: scheduler.submit(lambda: note("submitted")))
    scheduler.at(2.25, pause)
    scheduler.at(2.25, lambda: note("same time"))
    scheduler.run_until(3.0)
    seen.append(("end", clock.time))
    scheduler.run_until(3.0)  # nothing due: the clock stays
    seen.append(("again", clock.time))
    return seen


def test_a_job_that_moves_the_clock_or_plays_it_is_followed():
    seen = _journey(SimulatedClock())
    assert ("overrun", 0.5) in seen and ("already past", 1.2) in seen
    assert ("play", 1.5) in seen and ("submitted", 2.0) in seen
    assert seen[-2:] == [("end", 3.0), ("again", 3.0)]


@settings(max_examples=20, deadline=None)
@given(st.lists(st.integers(1, 200), min_size=1, max_size=4))
def test_jobs_from_other_threads_run_once_each_in_each_threads_order(bursts):
    # senders submit bursts while the wall-clock loop runs, sleeps and wakes: every job runs
    # exactly once, on the loop's thread, each sender's jobs in the order it submitted them
    scheduler = Scheduler(MonotonicClock())
    loop_thread: list[threading.Thread] = []
    ran: list[tuple[int, int]] = []
    total = sum(bursts)

    def job(sender: int, n: int) -> None:
        loop_thread.append(threading.current_thread())
        ran.append((sender, n))
        if len(ran) == total:
            scheduler.stop()

    def send(sender: int, count: int) -> None:
        for n in range(count):
            scheduler.submit(partial(job, sender, n))

    senders = [threading.Thread(target=send, args=(k, count)) for k, count in enumerate(bursts)]
    for sender in senders:
        sender.start()
    scheduler.run_until(scheduler.time + 30)  # ends at the last job, or fails the count below
    for sender in senders:
        sender.join()
    assert len(ran) == total and set(loop_thread) == {threading.current_thread()}
    for k, count in enumerate(bursts):
        assert [n for sender, n in ran if sender == k] == list(range(count))
