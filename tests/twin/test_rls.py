"""RecursiveLeastSquares: exact on noise-free data, the batch solution with a vague prior,
forgetting follows a change, weights, persistence, and clear errors."""

from __future__ import annotations

import json
import math
import random
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.twin import RecursiveLeastSquares, TwinError

coefficients = st.lists(st.floats(-10, 10, allow_nan=False), min_size=1, max_size=4)


def batch_least_squares(rows, targets):
    """The normal equations solved by Gauss-Jordan elimination with partial pivoting."""
    n = len(rows[0])
    a = [[sum(r[i] * r[j] for r in rows) for j in range(n)] for i in range(n)]
    b = [sum(r[i] * y for r, y in zip(rows, targets, strict=True)) for i in range(n)]
    for col in range(n):
        pivot = max(range(col, n), key=lambda r: abs(a[r][col]))
        a[col], a[pivot], b[col], b[pivot] = a[pivot], a[col], b[pivot], b[col]
        for r in range(n):
            if r != col:
                f = a[r][col] / a[col][col]
                a[r] = [x - f * y for x, y in zip(a[r], a[col], strict=True)]
                b[r] -= f * b[col]
    return [b[i] / a[i][i] for i in range(n)]


def observations(theta, count, seed, noise=0.0):
    rng = random.Random(seed)
    for _ in range(count):
        phi = [rng.uniform(-2, 2) for _ in theta]
        yield phi, sum(p * t for p, t in zip(phi, theta, strict=True)) + rng.gauss(0, noise)


@settings(max_examples=40, deadline=None)
@given(theta=coefficients, seed=st.integers(0, 10_000))
def test_noise_free_data_give_the_true_parameters(theta, seed):
    rls = RecursiveLeastSquares(len(theta), covariance=1e8)
    for phi, y in observations(theta, 20 * len(theta), seed):
        rls.update(phi, y)
    assert rls.theta == pytest.approx(theta, abs=1e-5)


@settings(max_examples=30, deadline=None)
@given(theta=coefficients, seed=st.integers(0, 10_000), noise=st.floats(0.01, 1.0))
def test_with_a_vague_prior_the_estimate_is_the_batch_least_squares_solution(theta, seed, noise):
    data = list(observations(theta, 50, seed, noise))
    rls = RecursiveLeastSquares(len(theta), covariance=1e9)
    for phi, y in data:
        rls.update(phi, y)
    batch = batch_least_squares([phi for phi, _ in data], [y for _, y in data])
    assert rls.theta == pytest.approx(batch, abs=1e-5)


def test_forgetting_follows_a_change_that_plain_least_squares_averages_away():
    before, after = [1.0, -2.0], [3.0, 0.5]
    forgetful = RecursiveLeastSquares(2, forgetting=0.95)
    stubborn = RecursiveLeastSquares(2)
    for phi, y in [*observations(before, 500, 1), *observations(after, 200, 2)]:
        forgetful.update(phi, y)
        stubborn.update(phi, y)
    assert forgetful.theta == pytest.approx(after, abs=1e-3)
    assert stubborn.theta[0] < 2.5  # still half in the old regime


def test_a_weight_of_two_is_the_same_observation_twice():
    once, twice = (
        RecursiveLeastSquares(2, covariance=10.0),
        RecursiveLeastSquares(2, covariance=10.0),
    )
    for phi, y in observations([0.5, 1.5], 10, 3, noise=0.1):
        once.update(phi, y, weight=2.0)
        twice.update(phi, y)
        twice.update(phi, y)
    assert once.theta == pytest.approx(twice.theta, rel=1e-9)
    for row_once, row_twice in zip(once.P, twice.P, strict=True):
        assert row_once == pytest.approx(row_twice, rel=1e-9)


def test_the_update_returns_the_a_priori_error_and_the_covariance_stays_symmetric():
    rls = RecursiveLeastSquares(3, initial=[1.0, 2.0, 3.0])
    assert rls.update([1.0, 1.0, 1.0], 10.0) == pytest.approx(4.0)
    for phi, y in observations([1.0, 1.0, 1.0], 100, 4, noise=0.5):
        rls.update(phi, y)
    assert all(rls.P[i][j] == rls.P[j][i] for i in range(3) for j in range(3))


def test_max_trace_bounds_the_covariance_of_directions_never_excited():
    rls = RecursiveLeastSquares(2, forgetting=0.9, covariance=1.0, max_trace=5.0)
    for _ in range(200):
        rls.update([1.0, 0.0], 1.0)  # the second parameter is never seen
    assert rls.P[0][0] + rls.P[1][1] <= 5.0 + 1e-9


def test_reset_covariance_keeps_the_estimate_and_learns_fast_again():
    rls = RecursiveLeastSquares(1, covariance=100.0)
    for phi, y in observations([2.0], 1000, 5, noise=0.1):
        rls.update(phi, y)
    slow = rls.P[0][0]
    rls.reset_covariance()
    assert rls.theta[0] == pytest.approx(2.0, abs=0.05)
    assert rls.P[0][0] == 100.0 > slow


def test_the_state_survives_json_and_continues_identically():
    rls = RecursiveLeastSquares(2, forgetting=0.99)
    data = list(observations([1.0, -1.0], 40, 6, noise=0.2))
    for phi, y in data[:20]:
        rls.update(phi, y)
    copy = RecursiveLeastSquares(2, forgetting=0.99)
    copy.restore(json.loads(json.dumps(rls.state())))
    for phi, y in data[20:]:
        assert copy.update(phi, y) == rls.update(phi, y)
    assert copy.theta == rls.theta and copy.points == rls.points == 40


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: RecursiveLeastSquares(0), "n >= 1"),
        (lambda: RecursiveLeastSquares(2, forgetting=1.5), "forgetting factor"),
        (lambda: RecursiveLeastSquares(2, initial=[1.0]), "initial has 1 values"),
        (lambda: RecursiveLeastSquares(2, covariance=[[1.0]]), "must be 2x2"),
        (lambda: RecursiveLeastSquares(2, covariance=-1.0), "positive diagonal"),
        (lambda: RecursiveLeastSquares(2).update([1.0], 1.0), "phi has 1 values"),
        (lambda: RecursiveLeastSquares(1).update([1.0], 1.0, weight=0), "weight"),
        (lambda: RecursiveLeastSquares(1).restore({"theta": [1.0]}), "not a least-squares"),
    ],
)
def test_misuse_is_a_twin_error_that_says_what_is_wrong(make, message):
    with pytest.raises(TwinError, match=message):
        make()


class Loops:
    """The textbook update in loops, every sum added left to right (as ``sum()`` of floats
    did up to Python 3.11; later versions compensate its rounding)."""

    def __init__(self, rls):
        self.theta, self.P, self.forgetting = list(rls.theta), [r[:] for r in rls.P], rls.forgetting
        self.max_trace = rls.max_trace

    @staticmethod
    def total(values):
        out = 0.0
        for value in values:
            out += value
        return out

    def variance_factor(self, phi):
        return self.total(
            phi[i] * self.total(self.P[i][j] * phi[j] for j in range(3)) for i in range(3)
        )

    def update(self, phi, y, weight):
        P, total = self.P, self.total
        error = y - total(p * t for p, t in zip(phi, self.theta, strict=True))
        Pphi = [total(P[i][j] * phi[j] for j in range(3)) for i in range(3)]
        denominator = self.forgetting / weight + total(phi[i] * Pphi[i] for i in range(3))
        gain = [v / denominator for v in Pphi]
        self.theta = [t + g * error for t, g in zip(self.theta, gain, strict=True)]
        new = [[0.0] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                new[i][j] = new[j][i] = (P[i][j] - gain[i] * Pphi[j]) * (1.0 / self.forgetting)
        trace = total(new[i][i] for i in range(3))
        if self.max_trace is not None and trace > self.max_trace:
            new = [[x * (self.max_trace / trace) for x in row] for row in new]
        self.P = new
        return error


@settings(max_examples=60, deadline=None)
@given(
    data=st.lists(
        st.tuples(
            st.lists(st.floats(-10, 10), min_size=3, max_size=3),
            st.floats(-100, 100),
            st.floats(0.01, 10),
        ),
        min_size=1,
        max_size=40,
    ),
    forgetting=st.floats(0.8, 1.0),
    covariance=st.lists(st.floats(1e-3, 1e6), min_size=3, max_size=3),
    max_trace=st.one_of(st.none(), st.floats(1e-2, 1e7)),
)
def test_three_parameters_take_an_unrolled_update_with_the_loops_floats(
    data, forgetting, covariance, max_trace
):
    rls = RecursiveLeastSquares(
        3, forgetting=forgetting, covariance=covariance, max_trace=max_trace
    )
    # update3 (the numbers given one by one) and variances_within (several phis) on another
    three = RecursiveLeastSquares(
        3, forgetting=forgetting, covariance=covariance, max_trace=max_trace
    )
    loops = Loops(rls)
    previous = data[0][0]
    for phi, y, weight in data:
        # the same operations in the same order: the same floats, to the last bit
        assert rls.variance_factor(phi) == loops.variance_factor(phi)
        for bound in (loops.variance_factor(phi), loops.variance_factor(previous), 1.0):
            expected = all(loops.variance_factor(p) <= bound for p in (phi, previous))
            assert three.variances_within((phi, previous), bound) is expected
        error = loops.update(phi, y, weight)
        assert rls.update(phi, y, weight) == error
        assert three.update3(phi[0], phi[1], phi[2], y, weight) == error
        assert rls.theta == three.theta == loops.theta and rls.P == three.P == loops.P
        previous = phi
    assert rls.points == three.points == len(data)


def test_update3_and_variances_within_refuse_what_update_refuses():
    with pytest.raises(TwinError, match="weight"):
        RecursiveLeastSquares(3).update3(1.0, 1.0, 1.0, 1.0, weight=0.0)
    with pytest.raises(TwinError, match="3 parameters"):
        RecursiveLeastSquares(2).update3(1.0, 1.0, 1.0, 1.0)
    two = RecursiveLeastSquares(2, covariance=2.0)
    assert two.variances_within([[1.0, 0.0], [0.0, 1.0]], 2.0)
    assert not two.variances_within([[1.0, 0.0], [1.0, 1.0]], 2.0)


def _differs_on_as_first_written(live, phis, theta, tolerance):
    """The Hotbox twin's publication test before it moved here (its loop, three terms)."""
    old0, old1, old2 = theta
    new0, new1, new2 = live
    step0, step1, step2 = new0 - old0, new1 - old1, new2 - old2
    for p0, p1, p2 in phis:
        flows = abs(p0 * old0) + abs(p1 * old1) + abs(p2 * old2)
        moved = p0 * step0 + p1 * step1 + p2 * step2
        if abs(moved) > tolerance * flows:
            return True
    return False


def _differs_on_in_loops(live, phis, theta, tolerance):
    return any(
        abs(sum(p * (new - old) for p, new, old in zip(phi, live, theta, strict=True)))
        > tolerance * sum(abs(p * old) for p, old in zip(phi, theta, strict=True))
        for phi in phis
    )


numbers = st.floats(-1e6, 1e6) | st.sampled_from([0.0, -0.0, math.inf, math.nan, 1e-300])


@settings(max_examples=300, deadline=None, database=None)
@given(
    live=st.lists(numbers, min_size=3, max_size=3),
    theta=st.lists(numbers, min_size=3, max_size=3),
    phis=st.lists(st.tuples(numbers, numbers, numbers), max_size=3),
    tolerance=st.floats(0.0, 1.0) | st.integers(0, 2),
)
def test_differs_on_is_the_twins_publication_test_as_first_written(live, theta, phis, tolerance):
    rls = RecursiveLeastSquares(3)
    rls.theta = list(live)
    expected = _differs_on_as_first_written(live, phis, tuple(theta), tolerance)
    assert rls.differs_on(phis, tuple(theta), tolerance) is expected
    assert rls.differs_on(iter(phis), theta, tolerance) is expected  # any iterable, sequences


@settings(max_examples=100, deadline=None, database=None)
@given(
    data=st.integers(1, 5).flatmap(
        lambda n: st.tuples(
            st.lists(st.floats(-100, 100), min_size=n, max_size=n),
            st.lists(st.floats(-100, 100), min_size=n, max_size=n),
            st.lists(st.lists(st.floats(-100, 100), min_size=n, max_size=n), max_size=3),
        )
    ),
    tolerance=st.floats(0.0, 1.0),
)
def test_differs_on_any_number_of_parameters_is_the_definition(data, tolerance):
    live, theta, phis = data
    rls = RecursiveLeastSquares(len(live))
    rls.theta = list(live)
    assert rls.differs_on(phis, theta, tolerance) is _differs_on_in_loops(
        live, phis, theta, tolerance
    )


@settings(max_examples=60, deadline=None, database=None)
@given(
    phi=st.lists(st.integers(-1000, 1000), min_size=3, max_size=3),
    y=st.integers(-1000, 1000),
    weight=st.integers(1, 5),
    previous=st.lists(st.integers(-1000, 1000), min_size=3, max_size=3),
)
def test_the_three_parameter_paths_take_ints_as_the_loops_do(phi, y, weight, previous):
    # the numbers go through float(); with floats in the estimator an int computes as its float
    rls, floats = RecursiveLeastSquares(3, max_trace=5e3), RecursiveLeastSquares(3, max_trace=5e3)
    loops = Loops(rls)
    for bound in (0, 10**6, 10**9):
        assert rls.variances_within((phi, previous), bound) is all(
            loops.variance_factor(p) <= bound for p in (phi, previous)
        )
    error = loops.update([float(p) for p in phi], float(y), float(weight))
    assert floats.update3(*map(float, phi), float(y), float(weight)) == error
    assert rls.update3(*phi, y, weight) == error
    assert rls.theta == floats.theta == loops.theta and rls.P == floats.P == loops.P


def _python_zero_division() -> str:
    """What this Python says when a float is divided by zero."""
    with pytest.raises(ZeroDivisionError) as raised:
        1.0 / 0.0  # noqa: B018 - the division is the test
    return str(raised.value)


def test_a_zero_divisor_raises_pythons_own_zero_division_error_and_changes_nothing():
    # the compiled build divides C doubles; its own error would read "float division"
    message = f"^{_python_zero_division()}$"
    rls = RecursiveLeastSquares(3, covariance=2.0)
    with pytest.raises(ZeroDivisionError, match=message):  # forgetting / inf + phi' P phi == 0
        rls.update3(0.0, 0.0, 0.0, 1.0, weight=math.inf)
    assert (
        rls.theta == [0.0, 0.0, 0.0]
        and rls.P == [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]
        and rls.points == 0
    )
    shrunk = RecursiveLeastSquares(3, max_trace=-1.0)  # a trace of 0 is above it
    shrunk.P = [[0.0] * 3 for _ in range(3)]
    with pytest.raises(ZeroDivisionError, match=message):
        shrunk.update3(1.0, 1.0, 1.0, 1.0)
    assert shrunk.points == 0
    with pytest.raises(ZeroDivisionError, match=message):  # positive, but 0.0 as a float
        RecursiveLeastSquares(3).update3(1.0, 1.0, 1.0, 1.0, weight=Fraction(1, 10**400))
    unforgetting = RecursiveLeastSquares(3, covariance=2.0)
    unforgetting.forgetting = 0.0  # only after construction; theta is updated before 1 / 0
    with pytest.raises(ZeroDivisionError, match=message):
        unforgetting.update3(1.0, 1.0, 1.0, 3.0)
    assert unforgetting.theta == [1.0, 1.0, 1.0] and unforgetting.points == 0
