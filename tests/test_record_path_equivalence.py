"""The per-record fast paths give what the general code they replace gives, for any input.

Each test keeps the straightforward version (as it was written before it was made faster) and
checks the fast one against it: knowledge read under one lock, the Page-Hinkley update with its
min() and statistic written out, the Hotbox simulator's step with min/max written out.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.values import Declaration, make_check
from rasm.twin import PageHinkley

SETTINGS = settings(max_examples=300, deadline=None, database=None)
FLOATS = st.floats(allow_nan=True, allow_infinity=True)


def _same(a, b) -> bool:
    """Equal and of the same type, a nan equal to a nan."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and math.isnan(a):
        return math.isnan(b)
    return a == b


# -------------------------------------------------------------------- knowledge: read_values

KEYS = st.sampled_from(["a", "b", "c", "missing"])


@SETTINGS
@given(
    st.lists(st.tuples(KEYS, st.floats(-10, 10) | st.booleans() | st.text(max_size=3))),
    st.lists(KEYS, max_size=5),
    st.none() | st.integers(),
)
def test_read_values_is_read_knowledge_of_each_key(writes, keys, default):
    kb = KnowledgeBase(default_history=3)
    for time, (key, value) in enumerate(writes):
        try:
            kb.register_knowledge(key, value, float(time))
        except Exception:  # a value of another type than the key's first: refused, as ever
            pass
    assert kb.read_values(keys, default) == {k: kb.read_knowledge(k, default) for k in keys}


BOUNDS = st.none() | st.integers(-5, 5) | st.floats(-5, 5) | st.sampled_from([-math.inf, math.inf])
ANY_VALUE = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(-(2**1100), 2**1100)
    | FLOATS
    | st.text(max_size=3)
    | st.lists(st.integers(), max_size=2)
)


@SETTINGS
@given(st.sampled_from(["float", "int", "bool", "str", "json"]), BOUNDS, BOUNDS, ANY_VALUE)
def test_a_stored_value_is_what_its_declarations_check_makes_of_it(kind, lo, hi, value):
    numeric = kind in ("float", "int")
    if numeric and lo is not None and hi is not None and lo > hi:
        lo, hi = hi, lo
    decl = Declaration("k", kind, minimum=lo if numeric else None, maximum=hi if numeric else None)
    kb = KnowledgeBase()
    kb.declare("k", kind, minimum=decl.minimum, maximum=decl.maximum)
    try:
        expected = make_check(decl)(value)
    except KnowledgeError as exc:
        with pytest.raises(KnowledgeError) as raised:
            kb.register_knowledge("k", value, 1.0)
        assert str(raised.value) == str(exc)
        assert kb.register_values({"k": value}, 1.0)["k"].args == exc.args
        return
    assert _same(kb.register_knowledge("k", value, 1.0).value, expected)
    assert kb.register_values({"k": value}, 2.0) == {}
    assert _same(kb.read_knowledge("k"), expected)


class _OwnReads(KnowledgeBase):
    """A store that reads its own way (as Redis does): read_values must ask it per key."""

    def read_knowledge(self, key, default=None):
        return ("own", key, default)


def test_read_values_asks_a_store_that_reads_its_own_way():
    kb = _OwnReads()
    assert kb.read_values(["x", "y"], 0) == {"x": ("own", "x", 0), "y": ("own", "y", 0)}


# -------------------------------------------------------------------- twin: Page-Hinkley


class _ReferencePageHinkley:
    """PageHinkley.update as first written (attributes, min(), the statistic property)."""

    def __init__(self, delta, threshold, min_samples):
        self.delta, self.threshold, self.min_samples = delta, threshold, min_samples
        self.detections = 0
        self.reset()

    def reset(self):
        self.samples, self.mean, self.cumulative, self.minimum = 0, 0.0, 0.0, 0.0

    def update(self, x):
        self.samples += 1
        self.mean += (x - self.mean) / self.samples
        self.cumulative += x - self.mean - self.delta
        self.minimum = min(self.minimum, self.cumulative)
        if self.samples >= self.min_samples and self.cumulative - self.minimum > self.threshold:
            self.detections += 1
            self.reset()
            return True
        return False


@SETTINGS
@given(
    st.lists(FLOATS | st.floats(0, 1), max_size=80),
    st.floats(0, 1),
    st.floats(0.01, 3),
    st.integers(1, 10),
)
def test_page_hinkley_update_is_the_reference_update(xs, delta, threshold, min_samples):
    fast = PageHinkley(delta=delta, threshold=threshold, min_samples=min_samples)
    slow = _ReferencePageHinkley(delta, threshold, min_samples)
    for x in xs:
        assert fast.update(x) == slow.update(x)
        for name in ("samples", "mean", "cumulative", "minimum", "detections"):
            assert _same(getattr(fast, name), getattr(slow, name)), name
    assert _same(fast.statistic, slow.cumulative - slow.minimum)


# -------------------------------------------------------------------- Hotbox simulator step


def _hotbox_components():
    path = Path(__file__).resolve().parents[1] / "examples" / "hotbox" / "components.py"
    spec = importlib.util.spec_from_file_location("hotbox_components_under_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _reference_step(sim, time: float, dt: float) -> dict:
    """HotboxSimulator.step as first written (min/max calls, attributes read each time)."""
    while sim.content_changes and sim.content_changes[0][0] <= time:
        sim.capacity = sim.content_changes.pop(0)[1]
    lid = sim.lid_open(time)
    loss = sim.LOSS_OPEN if lid else sim.LOSS_CLOSED
    feed_forward = sim.LOSS_CLOSED * (sim.settings["setpoint"] - sim.AMBIENT)
    wanted = feed_forward + sim.GAIN * (sim.settings["setpoint"] - sim.temperature)
    sim.power = min(max(wanted, 0.0), sim.settings["power_limit"])
    sim.temperature += dt * (sim.power - loss * (sim.temperature - sim.AMBIENT)) / sim.capacity
    measured = sim.temperature + sim.rng.gauss(0.0, 0.02)
    return {
        "hotbox/sensors": {
            "temperature": round(measured, 4),
            "lid_open": lid,
            "heater_power": round(sim.power, 3),
            "heater_mode": sim.settings["mode"],
            "setpoint": sim.settings["setpoint"],
        }
    }


LIMITS = st.floats(0, 200) | st.integers(0, 200) | st.sampled_from([math.nan, math.inf])


@SETTINGS
@given(
    st.floats(-50, 150) | st.sampled_from([math.nan]),
    st.floats(0, 60) | st.integers(0, 60),
    LIMITS,
    st.integers(0, 3),
    st.lists(st.tuples(st.floats(0, 5), st.floats(10, 1000)), max_size=2),
)
def test_the_simulator_step_is_the_reference_step(temperature, setpoint, limit, seed, changes):
    module = _hotbox_components()
    scenario = {
        "initial_temperature": 37.5,
        "content_change": [list(c) for c in changes],
        "first_lid_opening": 1.0,
    }
    fast = module.HotboxSimulator(scenario, seed=seed)
    slow = module.HotboxSimulator(scenario, seed=seed)
    for sim in (fast, slow):
        sim.temperature = temperature
        sim.apply("heater", {"setpoint": setpoint, "power_limit": limit}, 0.0)
    for k in range(30):
        got, want = fast.step(0.1 * k, 0.1), _reference_step(slow, 0.1 * k, 0.1)
        assert list(got) == list(want)
        for name, value in want["hotbox/sensors"].items():
            assert _same(got["hotbox/sensors"][name], value), name
        assert _same(fast.power, slow.power) and _same(fast.temperature, slow.temperature)


# -------------------------------------------------------------------- twin: the Hotbox's learning


def _hotbox_twin_module():
    from tests.twin.hotbox import twin_module

    return twin_module


class _ReferenceWindow:
    """SlidingWindow.push as first written (the last entry read three times, the counter
    read back)."""

    @staticmethod
    def push(window, time, temperature, power, lid):
        entries = window._entries
        if entries and time - entries[-1][0] > window.max_gap:
            window.clear()
        if entries:
            before_time, before_temperature = entries[-1][0], entries[-1][1]
            step = time - before_time
            excess = before_temperature - _hotbox_twin_module().AMBIENT
            term_power = step * power
            term_loss = step * excess
            window.power += term_power
            window.loss += term_loss
            if lid:
                window.lid += term_loss
                window._lid_intervals += 1
            entries.append((time, temperature, term_power, term_loss, lid))
        else:
            entries.append((time, temperature, 0.0, 0.0, False))
        edge = time - window.span + 1e-9
        while len(entries) >= 2 and entries[1][0] <= edge:
            entries.popleft()
            _, _, term_power, term_loss, lid_open = entries[0]
            window.power -= term_power
            window.loss -= term_loss
            if lid_open:
                window.lid -= term_loss
                window._lid_intervals -= 1
        if not window._lid_intervals:
            window.lid = 0.0
        window._since_resum += 1
        if window._since_resum >= window.resum_every:
            window.resum()
        return entries[0][0] <= edge


def _reference_twin(**options):
    """A HotboxTwin learning as first written: rls.update with the phi tuple, two
    variance_factor calls, the reference window."""
    module = _hotbox_twin_module()

    class Reference(module.HotboxTwin):
        def observe(self, time, values):
            temperature = values.get("temperature")
            power = values.get("heater_power")
            if temperature is None or power is None:
                return None
            record = (float(time), float(temperature), float(power), bool(values.get("lid_open")))
            pending, update = self._pending, None
            if pending is not None and record[0] < pending[0]:
                return None
            if pending is not None and record[0] > pending[0]:
                update = self._learn(*pending)
            self._pending = record
            return update

        def _learn(self, time, temperature, power, lid):
            recent = self._recent
            if not _ReferenceWindow.push(recent, time, temperature, power, lid):
                return None
            a0, b0, c0 = self._scale
            phi = (a0 * recent.power, -b0 * recent.loss, -c0 * recent.lid)
            self._reference[lid] = phi
            change = recent.change
            error = self.rls.update(phi, change, 1.0 / (len(recent) - 1))
            residual = abs(error)
            self._errors += 1
            self._square_error += (error * error - self._square_error) / min(self._errors, 100)
            drift = False
            confident = self._confident()
            if self._armed:
                drift = self.detector.update(residual)
            elif confident and not self._relearning:
                self._armed = True
                self.detector.reset()
            if drift:
                self.drifts += 1
                self.rls.reset_covariance()
                self._armed = False
                self._relearning = True
                confident = False
            changed = confident and self._worth_publishing(time)
            if changed:
                self._publish(time)
            return module.TwinUpdate(residual, drift, changed)

        def _confident(self):
            reference = self._reference
            if len(reference) < 2:
                return False
            theta = self.rls.theta
            if theta[0] <= 0 or theta[1] <= 0 or theta[2] < 0:
                return False
            bound = self.confidence**2
            variance = self.rls.variance_factor
            return variance(reference[False]) <= bound and variance(reference[True]) <= bound

        def _worth_publishing(self, time):
            published = self._published
            if published["version"] == 0 or self._relearning:
                return True
            if time - published["learned_at"] < self.min_interval:
                return False
            old0, old1, old2 = self._published_theta
            new0, new1, new2 = self.rls.theta
            for p0, p1, p2 in self._reference.values():
                flows = abs(p0 * old0) + abs(p1 * old1) + abs(p2 * old2)
                moved = p0 * (new0 - old0) + p1 * (new1 - old1) + p2 * (new2 - old2)
                if abs(moved) > self.tolerance * flows:
                    return True
            return False

    return Reference(**options)


@settings(max_examples=50, deadline=None, database=None)
@given(
    st.integers(0, 10**6),  # the box's noise and plans
    st.floats(100.0, 1500.0),  # the content's heat capacity after the change...
    st.floats(5.0, 50.0),  # ...at this time
    st.lists(st.tuples(st.integers(0, 599), st.sampled_from([-0.3, 0.0, 0.05, 1.5])), max_size=6),
    st.floats(0.003, 0.05),  # drift_delta: small ones make drift (and relearning) frequent
    st.floats(0.05, 1.5),  # drift_threshold
    st.floats(0.3, 5.0),  # confidence: large ones make a model confident (published) early
    st.integers(2, 300),  # resum_every
)
def test_the_hotbox_twin_learns_as_the_reference_learning(
    seed, capacity, change_at, glitches, delta, threshold, confidence, resum_every
):
    from tests.twin.hotbox import box

    options = dict(
        drift_delta=delta,
        drift_threshold=threshold,
        drift_min_samples=5,
        confidence=confidence,
        min_interval=1.0,
    )
    fast = _hotbox_twin_module().HotboxTwin(**options)
    slow = _reference_twin(**options)
    fast._recent.resum_every = slow._recent.resum_every = resum_every
    simulator = box(500.0, 2.0, 12.0)(
        {"first_lid_opening": 3.0, "lid_every": 12.0, "lid_open_for": 5.0,
         "content_change": [[change_at, capacity]]},
        seed=seed,
    )
    shifts = dict(glitches)  # record n's time moved (back, repeated, or a hole after it)
    for n in range(1, 601):
        time = round(n * 0.1, 9) + shifts.get(n, 0.0)
        if n % 50 == 0:
            simulator.apply("heater", {"mode": "boost" if n % 100 else "normal",
                                       "setpoint": 36.0 + (seed + n) % 4}, time)
        signals = simulator.step(time, 0.1)["hotbox/sensors"]
        values = {k: signals[k] for k in fast.inputs}
        got, want = fast.observe(time, values), slow.observe(time, values)
        assert repr(got) == repr(want) and type(got) is type(want)
        assert repr((fast.rls.theta, fast.rls.P)) == repr((slow.rls.theta, slow.rls.P))
    assert repr(fast.model()) == repr(slow.model())
    assert repr(vars(fast._recent)) == repr(vars(slow._recent))
    assert (fast.drifts, fast._armed, fast._relearning) == (
        slow.drifts, slow._armed, slow._relearning
    )


def _outcome(call, *args):
    """What a call gave: its answer's repr, or the exception's type and message."""
    try:
        return repr(call(*args))
    except Exception as exc:  # noqa: BLE001 - the exceptions are compared
        return f"raised {type(exc).__name__}: {exc}"


@settings(max_examples=30, deadline=None, database=None)
@given(
    st.integers(0, 10**6),  # the box's noise and plans
    st.sampled_from(["missing", None, "yesterday", 2, 2.0, -50.0]),  # the model's learned_at
    st.integers(0, 3),  # its version
    st.integers(2, 4),  # confident at records whose count is not a multiple of this
)
def test_the_twin_asks_confidence_and_publication_as_the_reference_does(
    seed, learned_at, version, period
):
    """Confidence and publication are asked in another order than the reference asks them:
    the same answers and, for a hand-written model whose learned_at is not a number, the
    same failures on the same records. Confidence is scripted (the same for both twins), so
    that armed twins also meet records where they are not confident."""
    from tests.twin.hotbox import box

    twins = fast, slow = (
        _hotbox_twin_module().HotboxTwin(min_interval=1.0),
        _reference_twin(min_interval=1.0),
    )
    model = {
        "version": version,
        "params": {"heat_capacity": 450.0, "loss_closed": 2.5, "loss_open": 11.0},
    }
    if learned_at != "missing":
        model["learned_at"] = learned_at
    for twin in twins:
        twin.load(dict(model))
        twin._confident = lambda twin=twin: twin.rls.points % period != 0
    simulator = box(450.0, 2.5, 11.0)(
        {"first_lid_opening": 2.0, "lid_every": 6.0, "lid_open_for": 3.0}, seed=seed
    )
    for n in range(1, 201):
        time = round(n * 0.1, 9)
        signals = simulator.step(time, 0.1)["hotbox/sensors"]
        values = {k: signals[k] for k in fast.inputs}
        assert _outcome(fast.observe, time, values) == _outcome(slow.observe, time, values)
        assert repr((fast.rls.theta, fast._armed, fast.detector.samples)) == repr(
            (slow.rls.theta, slow._armed, slow.detector.samples)
        )
    assert repr(fast.model()) == repr(slow.model())
