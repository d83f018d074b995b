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


def _differs_on_in_loops(live, phis, theta, tolerance):
    return any(
        abs(sum(p * (new - old) for p, new, old in zip(phi, live, theta, strict=True)))
        > tolerance * sum(abs(p * old) for p, old in zip(phi, theta, strict=True))
        for phi in phis
    )


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


def _python_zero_division() -> str:
    """What this Python says when a float is divided by zero."""
    with pytest.raises(ZeroDivisionError) as raised:
        1.0 / 0.0  # noqa: B018 - the division is the test
    return str(raised.value)


def test_variances_within_is_every_variance_factor_within_the_bound():
    two = RecursiveLeastSquares(2, covariance=2.0)
    assert two.variances_within([[1.0, 0.0], [0.0, 1.0]], 2.0)
    assert not two.variances_within([[1.0, 0.0], [1.0, 1.0]], 2.0)


def test_a_zero_divisor_raises_zero_division_error_and_counts_no_point():
    message = f"^{_python_zero_division()}$"
    rls = RecursiveLeastSquares(3, covariance=2.0)
    with pytest.raises(ZeroDivisionError, match=message):  # forgetting / inf + phi' P phi == 0
        rls.update([0.0, 0.0, 0.0], 1.0, weight=math.inf)
    assert (
        rls.theta == [0.0, 0.0, 0.0]
        and rls.P == [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]
        and rls.points == 0
    )
    with pytest.raises(ZeroDivisionError, match=message):  # positive, but 0.0 as a float
        RecursiveLeastSquares(3).update([1.0, 1.0, 1.0], 1.0, weight=Fraction(1, 10**400))
