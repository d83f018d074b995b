"""The Hotbox twin's window integrals are running sums: whatever the records (irregular steps,
gaps that restart the window, lid openings), they equal the sums recomputed over the window,
and a twin learning from them decides exactly as one that recomputes them at every record."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.twin.hotbox import HotboxTwin, box, drive, twin_module

SlidingWindow = twin_module.SlidingWindow
AMBIENT = twin_module.AMBIENT
EPSILON = 2.0**-52

records = st.lists(
    st.tuples(
        st.floats(0.01, 1.2),  # the step from the previous record (> max_gap: a restart)
        st.floats(-40.0, 150.0),  # temperature
        st.floats(0.0, 200.0),  # heater power
        st.booleans(),  # lid open
    ),
    min_size=30,  # long enough for windows of many records and several fresh sums
    max_size=300,
)


class Recomputed:
    """The window as the twin kept it before the running sums: the records themselves, the
    integrals summed over them afresh whenever asked."""

    def __init__(self, span: float, max_gap: float) -> None:
        self.span, self.max_gap = span, max_gap
        self.records: list[tuple[float, float, float, bool]] = []

    def push(self, time: float, temperature: float, power: float, lid: bool) -> bool:
        history = self.records
        if history and time - history[-1][0] > self.max_gap:
            history.clear()
        history.append((time, temperature, power, lid))
        edge = time - self.span + 1e-9
        while len(history) >= 2 and history[1][0] <= edge:
            history.pop(0)
        return history[0][0] <= edge

    def sums(self) -> tuple[float, float, float, float]:
        """(power, loss, lid, the sum of the terms' sizes) over the window, first to last."""
        power = loss = lid = size = 0.0
        for (before, temperature, _, _), (now, _, heat, lid_open) in zip(
            self.records, self.records[1:], strict=False
        ):
            step = now - before
            power += step * heat
            loss += step * (temperature - AMBIENT)
            if lid_open:
                lid += step * (temperature - AMBIENT)
            size += abs(step * heat) + 2 * abs(step * (temperature - AMBIENT))
        return power, loss, lid, size


@pytest.mark.slow
@settings(max_examples=100, deadline=None)
@given(
    records=records,
    span=st.floats(0.2, 5.0),
    resum_every=st.one_of(st.integers(1, 40), st.just(twin_module.RESUM_EVERY)),
)
def test_the_running_sums_are_the_sums_over_the_window(records, span, resum_every):
    window, reference = SlidingWindow(span, 1.0, resum_every), Recomputed(span, 1.0)
    time, largest = 0.0, 0.0
    for pushed, (step, temperature, power, lid) in enumerate(records, start=1):
        time += step
        assert window.push(time, temperature, power, lid) == reference.push(
            time, temperature, power, lid
        )
        assert len(window) == len(reference.records)
        assert window.change == reference.records[-1][1] - reference.records[0][1]
        power_sum, loss_sum, lid_sum, size = reference.sums()
        # each addition or subtraction since the last fresh sum rounds by at most half an ulp
        # of a running value no larger than the largest window seen (plus its newest term)
        largest = max(largest, size)
        tolerance = 4 * resum_every * EPSILON * largest
        assert window.power == pytest.approx(power_sum, abs=tolerance)
        assert window.loss == pytest.approx(loss_sum, abs=tolerance)
        assert window.lid == pytest.approx(lid_sum, abs=tolerance)
        if not any(lid_open for *_, lid_open in reference.records[1:]):
            assert window.lid == 0.0  # exactly: no drift makes up a lid-open interval
        if pushed % resum_every == 0:  # just summed afresh: no rounding carried over
            assert (window.power, window.loss, window.lid) == (power_sum, loss_sum, lid_sum)
    window.resum()  # summed afresh they are the recomputed sums to the last bit
    assert (window.power, window.loss, window.lid) == reference.sums()[:3]


def test_once_the_lid_intervals_leave_the_window_the_lid_integral_is_exactly_zero():
    window = SlidingWindow(1.0, 1.0)
    temperatures = [37.5 - 0.137 * k for k in range(15)] + [35.4 + 0.071 * k for k in range(15)]
    for k, temperature in enumerate(temperatures, start=1):
        window.push(round(0.1 * k, 9), temperature, 61.3, 3 <= k <= 15)
        if k == 15:
            assert window.lid > 1.0
    # the lid-open terms were added and subtracted in different orders: the running sum
    # would keep their rounding, but no interval in the window had the lid open
    assert window.lid == 0.0 and window.loss > 1.0


def test_a_twin_on_running_sums_decides_as_one_that_resums_at_every_record():
    def run(resum_every: int) -> list[tuple[float, float, bool, bool]]:
        twin = HotboxTwin()
        twin._recent = SlidingWindow(twin.window, twin.max_gap, resum_every)
        simulator = box(400.0, 2.0, 12.0)({"content_change": [[150.0, 150.0]]}, 7)
        updates = drive(twin, simulator, 300.0, seed=7, noise=0.02)
        return [(t, u.residual, u.drift, u.model_changed) for t, u in updates]

    running = run(twin_module.RESUM_EVERY)
    recomputed = run(1)  # as the twin did before the running sums: summed at every record
    assert any(d for *_, d, _ in running) and sum(c for *_, c in running) >= 3
    assert [(t, d, c) for t, _, d, c in running] == [(t, d, c) for t, _, d, c in recomputed]
    assert [r for _, r, _, _ in running] == pytest.approx(
        [r for _, r, _, _ in recomputed], abs=1e-12
    )
