"""Recursive least squares with a forgetting factor, in plain Python.

The twins rasm ships estimate a handful of parameters (the Hotbox: three), updated once per
record. At that size numpy's per-call overhead eats its advantage, so plain lists keep rasm free
of a numerical dependency. The estimator is exact (no approximation beyond floating point) and
its whole state is JSON-able, so a learned model can be persisted in knowledge and restored
after a restart.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from operator import mul
from typing import Any

from rasm.twin.base import TwinError

__all__ = ["RecursiveLeastSquares"]

Matrix = list[list[float]]


def _dot(a: Iterable[float], b: Iterable[float]) -> float:
    """The dot product, its terms added in order."""
    return sum(map(mul, a, b))


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
        if len(phi) != self.n:
            raise ValueError(f"phi has {len(phi)} values for {self.n} parameters")
        return _dot(phi, self.theta)

    def variance_factor(self, phi: Sequence[float]) -> float:
        """``phi' P phi``: how uncertain the prediction for ``phi`` is, in units of the noise."""
        return _dot(phi, [_dot(row, phi) for row in self.P])

    def variances_within(self, phis: Sequence[Sequence[float]], bound: float) -> bool:
        """True when ``variance_factor(phi) <= bound`` for every ``phi`` of ``phis`` (the
        first one beyond it ends the test)."""
        return all(self.variance_factor(phi) <= bound for phi in phis)

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
        phi = [float(v) for v in phi]
        error = float(y) - self.predict(phi)
        P = self.P
        Pphi = [_dot(row, phi) for row in P]
        denominator = self.forgetting / weight + _dot(phi, Pphi)
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
        steps = [new - old for new, old in zip(self.theta, theta, strict=True)]
        for phi in phis:
            flows = moved = 0.0
            for p, old, step in zip(phi, theta, steps, strict=True):
                flows += abs(p * old)
                moved += p * step
            if abs(moved) > tolerance * flows:
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
