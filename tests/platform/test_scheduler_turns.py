"""The scheduler's turn order, which a faster loop must keep: the jobs due now first, then the
inbox, then the clock moves on; a periodic job's turns stay at start + n * period."""

from __future__ import annotations

from sismic.clock import SimulatedClock

from rasm.platform.scheduler import Scheduler


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


class PropertyOnlyClock(SimulatedClock):
    """sismic's clock under another type: the scheduler reads and sets it only via ``time``."""


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


def test_sismic_clock_read_directly_moves_as_through_its_time_property():
    direct, general = _journey(SimulatedClock()), _journey(PropertyOnlyClock())
    assert direct == general
    assert ("overrun", 0.5) in direct and ("already past", 1.2) in direct
    assert direct[-2:] == [("end", 3.0), ("again", 3.0)]
