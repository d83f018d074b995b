"""rasm's SimulatedClock reads as sismic's does: the same time, the same errors, whatever is done
with it (set, started, sped up, stopped)."""

from __future__ import annotations

import pytest
import sismic.clock.clock as sismic_clock_module
from hypothesis import given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock as SismicClock

from rasm.statechart import clock as rasm_clock_module
from rasm.statechart.clock import SimulatedClock

TIMES = st.one_of(st.integers(-5, 50), st.floats(-5, 50, allow_nan=False))
OPERATIONS = st.lists(
    st.one_of(
        st.tuples(st.just("set"), TIMES),
        st.tuples(st.just("wait"), st.floats(0, 3)),  # the wall clock moves on
        st.tuples(st.just("speed"), st.floats(0.1, 4)),
        st.tuples(st.just("start"), st.none()),
        st.tuples(st.just("stop"), st.none()),
        st.tuples(st.just("read"), st.none()),
    ),
    max_size=25,
)


class _WallClock:
    """A stand-in for time.time() that moves only when told (both clocks read it)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _apply(clock, operation, value, wall) -> object:
    """What one operation gives: the time read, or the error raised."""
    try:
        if operation == "set":
            clock.time = value
        elif operation == "wait":
            wall.now += value
        elif operation == "speed":
            clock.speed = value
        elif operation == "start":
            clock.start()
        elif operation == "stop":
            clock.stop()
        return (clock.time, repr(clock), str(clock))
    except ValueError as exc:
        return ("ValueError", str(exc))


@settings(max_examples=300, deadline=None, database=None)
@given(OPERATIONS)
def test_rasm_simulated_clock_reads_as_sismics(operations):
    wall = _WallClock()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sismic_clock_module, "time", wall)
        patch.setattr(rasm_clock_module._time, "time", wall)
        ours, stock = SimulatedClock(), SismicClock()
        for operation, value in operations:
            ours_did = _apply(ours, operation, value, wall)
            stock_did = _apply(stock, operation, value, wall) if operation != "wait" else ours_did
            assert ours_did == stock_did
            assert type(ours.time) is type(stock.time)
    assert isinstance(ours, SismicClock)
