"""The Hotbox's digital twin: the box's thermal model, learned online.

The box obeys ``C dT/dt = P - k (T - T_ambient)`` with ``k = k_closed`` or, with the lid open,
``k_open``. Divided by ``C`` it is linear in three unknowns::

    dT/dt = a P - b (T - T_ambient) - c lid (T - T_ambient)
    a = 1/C    b = k_closed/C    c = (k_open - k_closed)/C

so recursive least squares learns them from (temperature, heater_power, lid_open) records.
One step's temperature change is mostly sensor noise (0.02 K of noise against a few hundredths
of a kelvin of change per 0.1 s), so the twin regresses the change over a ``window`` (1 s)
on the integrals of the inputs over that window ("integral method"): ten times the signal for
the same noise. ``TwinUpdate.residual`` is the a-priori error of that prediction, in kelvin:
``|T(now) - predicted T(now)|`` predicted from ``T(now - window)`` and the inputs since.

:meth:`HotboxTwin.simulate` runs the published model forward with the plan's controller
settings (the box's local P-controller: gain 25 W/K, feed-forward ``2 W/K x (set-point -
T_ambient)``, clipped to ``[0, power_limit]``), the lid held as it is now.
See docs/twin.md for the choices and their figures.
"""

from __future__ import annotations

import math
from collections import deque
from itertools import islice
from typing import Any

from rasm.twin import DigitalTwin, PageHinkley, RecursiveLeastSquares, TwinError, TwinUpdate

__all__ = ["HotboxTwin", "SlidingWindow"]

# the managed system's known parts: the room and the local controller (components.py)
AMBIENT = 20.0  # deg C
GAIN = 25.0  # W/K
FEED_FORWARD_LOSS = 2.0  # W/K: the controller's feed-forward term assumes the closed-lid loss
STEP = 0.1  # s: the longest integration step of simulate() (the box's own step)

NOMINAL = {"heat_capacity": 500.0, "loss_closed": 2.0, "loss_open": 12.0}
DEFAULT_SETTINGS = {"mode": "normal", "setpoint": 37.5, "power_limit": 60.0}
MODE_LIMITS = {"normal": 60.0, "boost": 100.0}  # power limits of the app's plans, by mode
PARAMS = ("heat_capacity", "loss_closed", "loss_open")


# the window's running sums are summed afresh after this many records, so the rounding of
# adding and subtracting terms never accumulates beyond a few hundred roundings (at most about
# 1e-13 of the sums' size); summing afresh costs one pass over the window, rarely
RESUM_EVERY = 256


class SlidingWindow:
    """The records of the last ``span`` seconds and the integrals the twin regresses on.

    For each interval between consecutive records (``step`` long, ending at a record with
    heater power ``P`` and lid state ``lid``, starting at temperature ``T``) the window adds
    ``step P``, ``step (T - T_ambient)`` and, when ``lid``, ``step (T - T_ambient)`` again:
    :attr:`power`, :attr:`loss` and :attr:`lid` are their sums over the window's intervals.
    They are running sums (the new interval's terms added, those of the records that leave the
    window subtracted), so a record costs the same whatever the window's length; every
    ``resum_every`` records they are summed afresh, in the window's order, so rounding never
    piles up, and the lid sum is exactly 0 whenever no interval in the window had the lid open.

    :meth:`push` keeps the window at least ``span`` long: the oldest record is dropped while
    the next one is still at least ``span`` old. Records more than ``max_gap`` after the last
    one restart the window (a hole is not learned from).
    """

    def __init__(self, span: float, max_gap: float, resum_every: int = RESUM_EVERY) -> None:
        self.span = span
        self.max_gap = max_gap
        self.resum_every = resum_every
        # (time, temperature, step P, step x, lid) with x = T_before - ambient: a record and
        # the terms of the interval ending at it (the first record's are unused)
        self._entries: deque[tuple[float, float, float, float, bool]] = deque()
        self.power = self.loss = self.lid = 0.0
        self._lid_intervals = 0  # intervals in the window with the lid open
        self._since_resum = 0

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def change(self) -> float:
        """The temperature change from the window's first record to its last."""
        return self._entries[-1][1] - self._entries[0][1]

    def clear(self) -> None:
        self._entries.clear()
        self.power = self.loss = self.lid = 0.0
        self._lid_intervals = 0

    def push(self, time: float, temperature: float, power: float, lid: bool) -> bool:
        """Add a record (later than the last one); True when the window spans ``span``."""
        entries = self._entries
        if entries:
            before_time, before_temperature, _, _, _ = entries[-1]
            if time - before_time > self.max_gap:
                self.clear()
        if entries:
            step = time - before_time
            excess = before_temperature - AMBIENT
            term_power = step * power
            term_loss = step * excess
            self.power += term_power
            self.loss += term_loss
            if lid:
                self.lid += term_loss
                self._lid_intervals += 1
            entries.append((time, temperature, term_power, term_loss, lid))
        else:
            entries.append((time, temperature, 0.0, 0.0, False))
        edge = time - self.span + 1e-9
        while len(entries) >= 2 and entries[1][0] <= edge:
            entries.popleft()
            # the interval into the new first record has left the window
            _, _, term_power, term_loss, lid_open = entries[0]
            self.power -= term_power
            self.loss -= term_loss
            if lid_open:
                self.lid -= term_loss
                self._lid_intervals -= 1
        if not self._lid_intervals:
            self.lid = 0.0
        since_resum = self._since_resum = self._since_resum + 1
        if since_resum >= self.resum_every:
            self.resum()
        return entries[0][0] <= edge

    def resum(self) -> None:
        """Sum the window's terms afresh, first interval to last."""
        self._since_resum = 0
        power = loss = lid = 0.0
        for _, _, term_power, term_loss, lid_open in islice(self._entries, 1, None):
            power += term_power
            loss += term_loss
            if lid_open:
                lid += term_loss
        self.power, self.loss, self.lid = power, loss, lid


def _to_theta(params: dict[str, float]) -> list[float]:
    """(C, k_closed, k_open) -> (a, b, c) of the linear model."""
    capacity = params["heat_capacity"]
    return [
        1.0 / capacity,
        params["loss_closed"] / capacity,
        (params["loss_open"] - params["loss_closed"]) / capacity,
    ]


def _to_params(theta: list[float]) -> dict[str, float]:
    """(a, b, c) -> (C, k_closed, k_open); a must be positive."""
    a, b, c = theta
    return {"heat_capacity": 1.0 / a, "loss_closed": b / a, "loss_open": (b + c) / a}


def _check_params(params: Any, where: str) -> dict[str, float]:
    if not isinstance(params, dict):
        raise TwinError(f"{where}: params must be a dict of {', '.join(PARAMS)}")
    out = {}
    for name in PARAMS:
        value = params.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TwinError(f"{where}: params.{name} must be a number, not {value!r}")
        if not (math.isfinite(value) and value > 0):
            raise TwinError(f"{where}: params.{name} must be positive and finite, not {value!r}")
        out[name] = float(value)
    return out


class HotboxTwin(DigitalTwin):
    """Learns the Hotbox's heat capacity and losses online; predicts plans with them.

    Options (all keyword; the defaults suit the Hotbox's sensor, 0.02 K of noise at 10 Hz):

    * ``prior``: the design model to start from (``{"heat_capacity": 500, "loss_closed": 2,
      "loss_open": 12}``) and ``prior_uncertainty``, its relative standard deviation (0.5).
    * ``window`` (s): the span each regression covers; ``noise`` (K): the standard deviation of
      a window's temperature change due to sensor noise alone (``sqrt(2) x`` the sensor's).
    * ``forgetting``: the least-squares forgetting factor per record (0.999: a memory of about
      100 s of records at 10 Hz).
    * ``confidence``: a learned model is *confident* when it has seen windows with the lid
      open and closed and, for the latest of each, the parameters' standard errors move the
      window's prediction by at most ``confidence x noise``. Only a confident model is
      published, and only a confident model arms the drift detector (large errors of a model
      still learning are not drift).
    * ``tolerance``, ``min_interval`` (s): a confident estimate becomes a new version when,
      on one of those two windows, its prediction differs from the published model's by more
      than ``tolerance`` of the window's heat flows (``|a P| + |b x| + |c x|`` integrated), at
      most once per ``min_interval`` (the first learned model, and the first after a drift, at
      once). Comparing predictions rather than parameters ignores the direction the closed
      loop hardly excites (k_closed and C together), where estimates wander without changing
      any prediction.
    * ``drift_delta`` (K), ``drift_threshold`` (K x records), ``drift_min_samples``: the
      Page-Hinkley test on the residuals (``rasm.twin.PageHinkley``).
    * ``max_gap`` (s): records further apart than this restart the window (a restart, a lost
      probe): the twin warms up again rather than learn from a hole.
    """

    inputs = ("temperature", "heater_power", "lid_open")

    def __init__(
        self,
        *,
        prior: dict[str, float] | None = None,
        prior_uncertainty: float = 0.5,
        window: float = 1.0,
        noise: float = 0.03,
        forgetting: float = 0.999,
        confidence: float = 0.5,
        tolerance: float = 0.02,
        min_interval: float = 5.0,
        drift_delta: float = 0.03,
        drift_threshold: float = 1.5,
        drift_min_samples: int = 20,
        max_gap: float = 1.0,
    ) -> None:
        self.prior = _check_params(dict(prior or NOMINAL), "prior")
        if not (window > 0 and noise > 0 and prior_uncertainty > 0 and max_gap > 0):
            raise TwinError("window, noise, prior_uncertainty and max_gap must be positive")
        self.window = float(window)
        self.noise = float(noise)
        self.confidence = float(confidence)
        self.tolerance = float(tolerance)
        self.min_interval = float(min_interval)
        self.max_gap = float(max_gap)
        # the estimator works on theta relative to the prior (all near 1): well conditioned
        self._scale = _to_theta(self.prior)
        variance = (prior_uncertainty / self.noise) ** 2
        self.rls = RecursiveLeastSquares(
            3,
            forgetting=forgetting,
            initial=[1.0, 1.0, 1.0],
            covariance=variance,
            max_trace=3 * variance,
        )
        self.detector = PageHinkley(
            delta=drift_delta, threshold=drift_threshold, min_samples=drift_min_samples
        )
        self._recent = SlidingWindow(self.window, self.max_gap)
        # phi of the latest window of each lid state
        self._reference: dict[bool, tuple[float, float, float]] = {}
        # the record waiting for a later time: (time, temperature, power, lid)
        self._pending: tuple[float, float, float, bool] | None = None
        self._armed = False  # the drift detector runs only while the live model is confident
        self._relearning = False
        self._square_error = 0.0
        self._errors = 0
        self.drifts = 0
        self._published = {
            "version": 0,
            "params": dict(self.prior),
            "learned_at": None,
            "points": 0,
            "rmse": None,
            "drifts": 0,
            "source": "prior",
        }
        # the published params as the estimator's theta: _worth_publishing compares the live
        # estimate with them at every record, so they are converted once, when published
        self._published_theta = self._relative(self.prior)

    # ------------------------------------------------------------------ learning

    def observe(self, time: float, values: dict[str, Any]) -> TwinUpdate | None:
        """Learn from the record before ``time`` once ``time`` moves past it.

        The runtime calls this once per registered input, so the record at ``time`` is complete
        only when a later time arrives: each call stores it, and the first call with a later
        time learns from it. A record missing the temperature or the power is skipped.
        """
        temperature = values.get("temperature")
        power = values.get("heater_power")
        if temperature is None or power is None:
            return None
        time = float(time)
        record = (time, float(temperature), float(power), bool(values.get("lid_open")))
        pending, update = self._pending, None
        if pending is not None:
            before = pending[0]
            if time < before:
                return None  # out of order: the contract says this does not happen; ignore it
            if time > before:
                update = self._learn(*pending)
        self._pending = record
        return update

    def _learn(self, time: float, temperature: float, power: float, lid: bool) -> TwinUpdate | None:
        recent = self._recent
        if not recent.push(time, temperature, power, lid):
            return None  # less than one window of records yet
        a0, b0, c0 = self._scale
        f0, f1, f2 = a0 * recent.power, -b0 * recent.loss, -c0 * recent.lid
        self._reference[lid] = (f0, f1, f2)
        # overlapping windows share their records: each counts as 1/len of an observation
        error = self.rls.update((f0, f1, f2), recent.change, 1.0 / (len(recent) - 1))
        residual = abs(error)
        self._errors += 1
        self._square_error += (error * error - self._square_error) / min(self._errors, 100)

        drift = False
        if self._armed:
            drift = self.detector.update(residual)
            if drift:
                self.drifts += 1
                self.rls.reset_covariance()
                self._armed = False
                self._relearning = True
            # a new version needs a confident estimate worth publishing; while armed the estimate
            # is nearly always confident and seldom worth publishing: the cheaper test goes first
            changed = not drift and self._worth_publishing(time) and self._confident()
        else:
            confident = self._confident()
            if confident and not self._relearning:
                self._armed = True
                self.detector.reset()
            changed = confident and self._worth_publishing(time)
        if changed:
            self._publish(time)
        return TwinUpdate(residual, drift, changed)

    def _confident(self) -> bool:
        """Physical estimates, both lid states seen, and for a window of each the parameters'
        uncertainty moves the prediction by less than ``confidence`` x the sensor noise."""
        reference = self._reference
        if len(reference) < 2:
            return False
        theta = self.rls.theta
        if theta[0] <= 0 or theta[1] <= 0 or theta[2] < 0:
            return False
        return self.rls.variances_within((reference[False], reference[True]), self.confidence**2)

    def _live_params(self) -> dict[str, float]:
        return _to_params([s * t for s, t in zip(self._scale, self.rls.theta, strict=True)])

    def _relative(self, params: dict[str, float]) -> tuple[float, float, float]:
        """``params`` as the estimator's theta (relative to the prior)."""
        a, b, c = (t / s for t, s in zip(_to_theta(params), self._scale, strict=True))
        return a, b, c

    def _worth_publishing(self, time: float) -> bool:
        """Whether a confident estimate is worth publishing now. Pure, so :meth:`_learn` may
        ask it before or after :meth:`_confident`."""
        published = self._published
        if published["version"] == 0 or self._relearning:
            return True
        if not isinstance(published.get("learned_at"), float) and not self._confident():
            # a hand-written model's learned_at may be anything (or missing): only a confident
            # estimate may trip over it, whichever of the two tests is asked first
            return False
        if time - published["learned_at"] < self.min_interval:
            return False
        # a new version when, on the latest window of either lid state, the live estimate and
        # the published model differ by more than `tolerance` of the window's heat flows
        return self.rls.differs_on(self._reference.values(), self._published_theta, self.tolerance)

    def _publish(self, time: float) -> None:
        if not self._armed:  # the first confident model: from now on large errors are drift
            self._armed = True
            self.detector.reset()
        self._relearning = False
        scale = self._scale
        theta = [s * t for s, t in zip(scale, self.rls.theta, strict=True)]
        covariance = [[scale[i] * scale[j] * self.rls.P[i][j] for j in range(3)] for i in range(3)]
        self._published = {
            "version": self._published["version"] + 1,
            "params": _to_params(theta),
            "learned_at": time,
            "points": self.rls.points,
            "rmse": math.sqrt(self._square_error),
            "drifts": self.drifts,
            "source": "learned",
            # the estimator's state in absolute units (a, b, c): learning resumes after load()
            "estimator": {"theta": theta, "covariance": covariance},
        }
        self._published_theta = self._relative(self._published["params"])

    # ------------------------------------------------------------------ the model

    def model(self) -> dict[str, Any]:
        """The published model (a copy): what :meth:`simulate` uses and what is persisted."""
        published = dict(self._published)
        published["params"] = dict(published["params"])
        if "estimator" in published:
            estimator = published["estimator"]
            published["estimator"] = {
                "theta": list(estimator["theta"]),
                "covariance": [list(row) for row in estimator["covariance"]],
            }
        return published

    def load(self, model: dict[str, Any]) -> None:
        """Continue from a persisted model: its parameters, version and estimator state."""
        if not isinstance(model, dict):
            raise TwinError(f"twin model: expected a JSON object, got {type(model).__name__}")
        version = model.get("version")
        if isinstance(version, bool) or not isinstance(version, int) or version < 0:
            raise TwinError(f"twin model: version must be an int >= 0, not {version!r}")
        params = _check_params(model.get("params"), "twin model")
        estimator = model.get("estimator")
        if estimator is not None:
            try:
                theta = [float(v) for v in estimator["theta"]]
                covariance = [[float(x) for x in row] for row in estimator["covariance"]]
            except (KeyError, TypeError, ValueError) as exc:
                raise TwinError(f"twin model: a damaged estimator state ({exc})") from exc
            if len(theta) != 3 or len(covariance) != 3 or any(len(r) != 3 for r in covariance):
                raise TwinError("twin model: the estimator state must be 3 values and 3x3")
            scale = self._scale
            self.rls.restore(
                {
                    "theta": [t / s for t, s in zip(theta, scale, strict=True)],
                    "covariance": [
                        [covariance[i][j] / (scale[i] * scale[j]) for j in range(3)]
                        for i in range(3)
                    ],
                    "points": model.get("points", 0),
                }
            )
        else:  # a hand-written model: start the estimator there, with the prior's uncertainty
            self.rls.theta = [t / s for t, s in zip(_to_theta(params), self._scale, strict=True)]
            self.rls.reset_covariance()
        self._published = dict(model)
        self._published["params"] = params
        self._published_theta = self._relative(params)
        self.drifts = int(model.get("drifts", 0) or 0)
        self._relearning = False
        self._armed = False
        self._recent.clear()
        self._pending = None

    # ------------------------------------------------------------------ prediction

    def simulate(
        self, plan: dict[str, Any], state: dict[str, Any], horizon: float, dt: float
    ) -> list[tuple[float, dict[str, Any]]]:
        """The box under ``plan``'s controller settings, from ``state``, lid held as it is.

        ``state`` needs ``temperature``; ``lid_open`` defaults to closed. Settings the plan
        does not give come from the state (``heater_mode``, ``setpoint``; the power limit is not
        reported, so it is the mode's usual one, 60 W normal and 100 W boost) and then from
        the normal mode. Each record carries the signals the box publishes.
        """
        if not (dt > 0 and horizon >= 0 and math.isfinite(horizon)):
            raise TwinError(f"simulate needs dt > 0 and a finite horizon >= 0, not {dt}, {horizon}")
        if not isinstance(state.get("temperature"), int | float):
            raise TwinError("simulate needs the current temperature in the state")
        settings = dict(DEFAULT_SETTINGS)
        if "heater_mode" in state:
            settings["mode"] = state["heater_mode"]
        if "setpoint" in state:
            settings["setpoint"] = state["setpoint"]
        settings.update({k: plan[k] for k in DEFAULT_SETTINGS if k in plan})
        if "power_limit" not in plan:  # the box does not report it: the mode's usual limit
            settings["power_limit"] = MODE_LIMITS.get(settings["mode"], settings["power_limit"])
        params = self._published["params"]
        capacity = params["heat_capacity"]
        lid = bool(state.get("lid_open", False))
        loss = params["loss_open"] if lid else params["loss_closed"]
        setpoint = float(settings["setpoint"])
        limit = float(settings["power_limit"])
        feed_forward = FEED_FORWARD_LOSS * (setpoint - AMBIENT)
        substeps = max(1, math.ceil(dt / STEP - 1e-9))
        h = dt / substeps
        temperature = float(state["temperature"])
        power = 0.0
        records = []
        for i in range(1, int(horizon / dt + 1e-9) + 1):
            for _ in range(substeps):
                wanted = feed_forward + GAIN * (setpoint - temperature)  # as the box computes it
                power = min(max(wanted, 0.0), limit)
                temperature += h * (power - loss * (temperature - AMBIENT)) / capacity
            records.append(
                (
                    round(i * dt, 9),
                    {
                        "temperature": temperature,
                        "heater_power": power,
                        "lid_open": lid,
                        "heater_mode": settings["mode"],
                        "setpoint": setpoint,
                    },
                )
            )
        return records
