"""Page-Hinkley: a jump of the mean is found within threshold / (jump - delta) samples (plus the
noise's share), stationary noise gives no alarm, and each detection starts afresh."""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.twin import PageHinkley, TwinError


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 100_000),
    level=st.floats(0.0, 1.0),
    spread=st.floats(0.0, 0.05),
)
def test_stationary_noise_never_raises_an_alarm(seed, level, spread):
    rng = random.Random(seed)
    detector = PageHinkley(delta=0.05, threshold=1.5, min_samples=20)
    assert not any(detector.update(abs(level + rng.gauss(0, spread))) for _ in range(5000))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), jump=st.floats(0.1, 1.0), spread=st.floats(0.0, 0.03))
def test_a_jump_of_the_mean_is_detected_within_the_bound(seed, jump, spread):
    rng = random.Random(seed)
    delta, threshold = 0.05, 1.5
    detector = PageHinkley(delta=delta, threshold=threshold, min_samples=20)
    for _ in range(200):
        assert not detector.update(0.02 + rng.gauss(0, spread))
    # after the jump the running mean creeps up, so allow twice the nominal delay, plus one
    bound = 2 * threshold / (jump - delta) + 1
    delay = next(n for n in range(1, 1000) if detector.update(0.02 + jump + rng.gauss(0, spread)))
    assert delay <= bound
    assert detector.detections == 1 and detector.samples == 0  # started afresh


def test_no_alarm_before_min_samples():
    detector = PageHinkley(delta=0.0, threshold=0.1, min_samples=10)
    values = [0.0] * 5 + [10.0] * 4
    assert not any(detector.update(v) for v in values)
    assert detector.update(10.0)


@pytest.mark.parametrize("kwargs", [{"delta": -1}, {"threshold": 0}, {"min_samples": 0}])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(TwinError, match="Page-Hinkley needs"):
        PageHinkley(**{"delta": 0.1, "threshold": 1.0, **kwargs})
