"""Recursive least squares with a forgetting factor, in plain Python.

The twins rasm ships estimate a handful of parameters (the Hotbox: three), updated once per
record. At that size numpy's per-call overhead eats its advantage, so plain lists keep rasm free
of a numerical dependency. Three parameters get an unrolled update (no loops, no temporary
lists: about 3 µs instead of 14 µs), written in the generic loops' order of operations so both
give the same floats. The estimator is exact (no approximation beyond floating point) and its
whole state is JSON-able, so a learned model can be persisted in knowledge and restored after a
restart.

"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from operator import truediv
from typing import Any

from rasm.twin.base import TwinError

__all__ = ["RecursiveLeastSquares"]

Matrix = list[list[float]]


def _divide_as_python(numerator: float, divisor: float) -> float:
    """``numerator / divisor``: called where the divisor is zero, it raises ZeroDivisionError."""
    return truediv(numerator, divisor)


def _diagonal(values: Sequence[float]) -> Matrix:
    n = len(values)
    return [[float(values[i]) if i == j else 0.0 for j in range(n)] for i in range(n)]


class RecursiveLeastSquares:
    """Estimate ``theta`` in ``y = phi · theta + noise`` one observation at a time.

    Minimises ``sum_i forgetting**(n-i) (y_i - phi_i · theta)**2`` plus the prior term
    ``(theta - initial)' P0^-1 (theta - initial)``: with ``forgetting`` below 1 old observations
    fade (memory about ``1 / (1 - forgetting)`` updates) so the estimate follows slow changes.

    * ``initial``: the prior estimate (default zeros).
    * ``covariance``: the prior ``P0``: a number (``P0 = covariance * I``), one number per
      parameter (a diagonal) or a full matrix. ``P`` times the noise variance is the estimate's
      covariance, so a large ``P0`` says "the prior is a guess".
    * ``max_trace``: with forgetting, directions the data never excite make ``P`` grow without
      bound ("wind-up"); when the trace of ``P`` exceeds ``max_trace`` it is scaled back to it.

    ``update(phi, y)`` returns the a-priori error ``y - phi · theta`` (before the update).
    ``reset_covariance()`` sets ``P`` back to ``P0`` (or to a given covariance) and keeps
    ``theta``: the estimator then learns from new data as fast as at the start — what a twin
    does after a drift.
    """

    def __init__(
        self,
        n: int,
        *,
        forgetting: float = 1.0,
        initial: Sequence[float] | None = None,
        covariance: float | Sequence[float] | Sequence[Sequence[float]] = 1e3,
        max_trace: float | None = None,
    ) -> None:
        if not (isinstance(n, int) and n >= 1):
            raise TwinError(f"RecursiveLeastSquares needs n >= 1 parameters, not {n!r}")
        if not (0.0 < forgetting <= 1.0):
            raise TwinError(f"the forgetting factor must be in (0, 1], not {forgetting!r}")
        self.n = n
        self.forgetting = float(forgetting)
        self.max_trace = None if max_trace is None else float(max_trace)
        self.initial_covariance = self._matrix(covariance)
        self.theta = [0.0] * n if initial is None else [float(v) for v in initial]
        if len(self.theta) != n:
            raise TwinError(f"initial has {len(self.theta)} values for {n} parameters")
        self.P = [row[:] for row in self.initial_covariance]
        self.points = 0

    def _matrix(self, value: Any) -> Matrix:
        n = self.n
        if isinstance(value, int | float):
            matrix = _diagonal([value] * n)
        elif len(value) == n and all(isinstance(v, int | float) for v in value):
            matrix = _diagonal(value)
        else:
            matrix = [[float(x) for x in row] for row in value]
        if len(matrix) != n or any(len(row) != n for row in matrix):
            raise TwinError(f"a covariance for {n} parameters must be {n}x{n}")
        if any(not math.isfinite(x) for row in matrix for x in row) or any(
            matrix[i][i] <= 0 for i in range(n)
        ):
            raise TwinError("a covariance needs finite values and a positive diagonal")
        return matrix

    # ------------------------------------------------------------------ estimation

    def predict(self, phi: Sequence[float]) -> float:
        """``phi · theta``: the prediction of the current estimate."""
        return sum(p * t for p, t in zip(phi, self.theta, strict=True))

    def variance_factor(self, phi: Sequence[float]) -> float:
        """``phi' P phi``: how uncertain the prediction for ``phi`` is, in units of the noise."""
        n = self.n
        P = self.P
        return sum(phi[i] * sum(P[i][j] * phi[j] for j in range(n)) for i in range(n))

    def variances_within(self, phis: Sequence[Sequence[float]], bound: float) -> bool:
        """True when ``variance_factor(phi) <= bound`` for every ``phi`` of ``phis`` (the
        first one beyond it ends the test)."""
        if self.n != 3:
            return all(self.variance_factor(phi) <= bound for phi in phis)
        # a twin asks this for its reference windows at every record: P read once, and
        # variance_factor's sums unrolled term for term (the same floats); float(): see the
        # module's docstring (bound is compared as given, as variance_factor's callers do)
        row0, row1, row2 = self.P
        p00, p01, p02 = float(row0[0]), float(row0[1]), float(row0[2])
        p10, p11, p12 = float(row1[0]), float(row1[1]), float(row1[2])
        p20, p21, p22 = float(row2[0]), float(row2[1]), float(row2[2])
        for f0, f1, f2 in phis:
            x0, x1, x2 = float(f0), float(f1), float(f2)
            variance = (
                x0 * (p00 * x0 + p01 * x1 + p02 * x2)
                + x1 * (p10 * x0 + p11 * x1 + p12 * x2)
                + x2 * (p20 * x0 + p21 * x1 + p22 * x2)
            )
            if not variance <= bound:
                return False
        return True

    def update(self, phi: Sequence[float], y: float, weight: float = 1.0) -> float:
        """Learn from one observation; returns the a-priori error ``y - phi · theta``.

        ``weight`` scales the observation's squared error in the criterion: an observation
        with weight 0.1 counts as a tenth of one (e.g. one of ten overlapping windows).
        """
        n = self.n
        if not weight > 0:
            raise TwinError(f"an observation's weight must be positive, not {weight!r}")
        if len(phi) != n:
            raise TwinError(f"phi has {len(phi)} values for {n} parameters")
        if n == 3:
            return self.update3(float(phi[0]), float(phi[1]), float(phi[2]), float(y), weight)
        return self._update(phi, y, weight)

    def _update(self, phi: Sequence[float], y: float, weight: float) -> float:
        """:meth:`update` for any ``n`` (arguments checked)."""
        n = self.n
        phi = [float(v) for v in phi]
        error = float(y) - self.predict(phi)
        P = self.P
        Pphi = [sum(P[i][j] * phi[j] for j in range(n)) for i in range(n)]
        denominator = self.forgetting / weight + sum(phi[i] * Pphi[i] for i in range(n))
        gain = [v / denominator for v in Pphi]
        self.theta = [t + g * error for t, g in zip(self.theta, gain, strict=True)]
        scale = 1.0 / self.forgetting
        # P <- (P - gain Pphi') / forgetting, kept exactly symmetric
        new = [[0.0] * n for _ in range(n)]
        for i in range(n):
            for j in range(i, n):
                value = (P[i][j] - gain[i] * Pphi[j]) * scale
                new[i][j] = new[j][i] = value
        if self.max_trace is not None:
            trace = sum(new[i][i] for i in range(n))
            if trace > self.max_trace:
                shrink = self.max_trace / trace
                new = [[x * shrink for x in row] for row in new]
        self.P = new
        self.points += 1
        return error

    def update3(self, f0: float, f1: float, f2: float, y: float, weight: float = 1.0) -> float:
        """:meth:`update` of a three-parameter estimator with ``phi = (f0, f1, f2)``, for a
        caller that has the numbers at hand (a twin, once per record): no sequence to check.
        The numbers are taken with ``float()``, as :meth:`update` takes ``phi`` and ``y``.

        Unrolled: every sum adds its terms in :meth:`_update`'s loops' order (and ``sum()`` of
        floats starting at 0 adds them left to right), so the two agree to the last bit on
        Python 3.11; from 3.12 on ``sum()`` compensates its rounding and the two may differ in
        the last digits.
        """
        if self.n != 3:
            raise TwinError(f"update3 is for 3 parameters; this estimator has {self.n}")
        if not weight > 0:
            raise TwinError(f"an observation's weight must be positive, not {weight!r}")
        x0, x1, x2, target, share = float(f0), float(f1), float(f2), float(y), float(weight)
        theta, (row0, row1, row2) = self.theta, self.P
        t0, t1, t2 = float(theta[0]), float(theta[1]), float(theta[2])
        p00, p01, p02 = float(row0[0]), float(row0[1]), float(row0[2])
        p10, p11, p12 = float(row1[0]), float(row1[1]), float(row1[2])
        p20, p21, p22 = float(row2[0]), float(row2[1]), float(row2[2])
        forgetting = float(self.forgetting)
        error = target - (x0 * t0 + x1 * t1 + x2 * t2)
        q0 = p00 * x0 + p01 * x1 + p02 * x2  # P phi
        q1 = p10 * x0 + p11 * x1 + p12 * x2
        q2 = p20 * x0 + p21 * x1 + p22 * x2
        # every divisor that may be zero is tested where the division is (Python's error)
        if not share:  # a positive weight whose float is 0
            _divide_as_python(forgetting, share)
        denominator = forgetting / share + (x0 * q0 + x1 * q1 + x2 * q2)
        if not denominator:
            _divide_as_python(q0, denominator)
        g0, g1, g2 = q0 / denominator, q1 / denominator, q2 / denominator
        self.theta = [t0 + g0 * error, t1 + g1 * error, t2 + g2 * error]
        if not forgetting:  # only if set to 0 after construction
            _divide_as_python(1.0, forgetting)
        scale = 1.0 / forgetting
        # P <- (P - gain Pphi') / forgetting from its upper triangle, kept exactly symmetric
        n00 = (p00 - g0 * q0) * scale
        n01 = (p01 - g0 * q1) * scale
        n02 = (p02 - g0 * q2) * scale
        n11 = (p11 - g1 * q1) * scale
        n12 = (p12 - g1 * q2) * scale
        n22 = (p22 - g2 * q2) * scale
        max_trace = self.max_trace
        if max_trace is not None:
            trace = n00 + n11 + n22
            if trace > max_trace:  # compared as given (an int is compared exactly)
                if not trace:
                    _divide_as_python(max_trace, trace)
                shrink = float(max_trace) / trace
                n00, n01, n02 = n00 * shrink, n01 * shrink, n02 * shrink
                n11, n12, n22 = n11 * shrink, n12 * shrink, n22 * shrink
        self.P = [[n00, n01, n02], [n01, n11, n12], [n02, n12, n22]]
        self.points += 1
        return error

    def differs_on(
        self, phis: Iterable[Sequence[float]], theta: Sequence[float], tolerance: float
    ) -> bool:
        """True when, for some ``phi`` of ``phis``, the estimate predicts ``phi`` differently
        from ``theta`` by more than ``tolerance`` of ``theta``'s terms there: ``|phi · (self.theta
        - theta)| > tolerance * sum |phi_i theta_i|`` (the first such ``phi`` ends the test).

        What a twin asks before publishing a new version of its model: has the live estimate
        moved in a direction its data see (``theta`` the published model, ``phis`` recent
        regressors)? Directions no ``phi`` excites are ignored, however far they wander.
        """
        current = self.theta
        if self.n != 3:
            steps = [new - old for new, old in zip(current, theta, strict=True)]
            for phi in phis:
                flows = moved = 0.0
                for p, old, step in zip(phi, theta, steps, strict=True):
                    flows += abs(p * old)
                    moved += p * step
                if abs(moved) > tolerance * flows:
                    return True
            return False
        # float(): see the module's docstring; the steps are the same for every phi
        old0, old1, old2 = float(theta[0]), float(theta[1]), float(theta[2])
        step0 = float(current[0]) - old0
        step1 = float(current[1]) - old1
        step2 = float(current[2]) - old2
        limit = float(tolerance)
        for f0, f1, f2 in phis:
            x0, x1, x2 = float(f0), float(f1), float(f2)
            flows = abs(x0 * old0) + abs(x1 * old1) + abs(x2 * old2)
            moved = x0 * step0 + x1 * step1 + x2 * step2
            if abs(moved) > limit * flows:
                return True
        return False

    def reset_covariance(self, covariance: Any = None) -> None:
        """``P`` back to the prior ``P0`` (or to ``covariance``); ``theta`` is kept."""
        source = self.initial_covariance if covariance is None else self._matrix(covariance)
        self.P = [row[:] for row in source]

    def standard_errors(self, noise_variance: float) -> list[float]:
        """Each parameter's standard error for a noise of variance ``noise_variance``."""
        return [math.sqrt(max(self.P[i][i], 0.0) * noise_variance) for i in range(self.n)]

    # ------------------------------------------------------------------ persistence

    def state(self) -> dict[str, Any]:
        """Everything needed to continue learning elsewhere (JSON-able)."""
        return {
            "theta": list(self.theta),
            "covariance": [row[:] for row in self.P],
            "points": self.points,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`state` (the forgetting factor and prior stay this object's)."""
        try:
            theta = [float(v) for v in state["theta"]]
            covariance = self._matrix(state["covariance"])
            points = int(state.get("points", 0))
        except (KeyError, TypeError, ValueError) as exc:
            raise TwinError(f"not a least-squares state: {exc}") from exc
        if len(theta) != self.n or not all(math.isfinite(v) for v in theta):
            raise TwinError(f"a least-squares state needs {self.n} finite parameters")
        self.theta, self.P, self.points = theta, covariance, points
