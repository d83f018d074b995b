"""How the runtime uses a digital twin: residual and model in knowledge, drift starts an
iteration, Legitimate rejects plans the twin predicts will break a property."""

from __future__ import annotations

from dataclasses import dataclass

from rasm import Platform, RunOptions

from .conftest import read_trace


@dataclass(frozen=True)
class Update:
    residual: float
    drift: bool
    model_changed: bool


class PessimistTwin:
    """Predicts that a normal-mode plan lets the box cool far below the band, where keeping the
    current settings would not."""

    inputs = ("temperature", "heater_power")

    def __init__(self, drift_at=None):
        self.points = 0
        self.loaded = None
        self.drift_at = drift_at

    def observe(self, time, values):
        self.points += 1
        drift = self.drift_at is not None and self.points == self.drift_at
        return Update(residual=0.01, drift=drift, model_changed=self.points % 50 == 0)

    def simulate(self, plan, state, horizon, dt):
        temperature = state.get("temperature", 37.0)
        # keeping the current settings (no mode in the plan) holds the temperature
        slope = {"boost": 0.05, None: 0.0}.get(plan.get("mode"), -0.5)
        steps = int(horizon / dt)
        return [
            (i * dt, {"temperature": temperature + slope * i * dt, "heater_power": 50.0})
            for i in range(steps + 1)
        ]

    def model(self):
        return {"version": self.points // 50, "params": {"points": self.points}}

    def load(self, model):
        self.loaded = model


def test_legitimate_rejects_plans_the_twin_predicts_unsafe(hotbox, tmp_path):
    class AlwaysNormalFirst:
        def plan(self, ctx):
            mode = "boost" if ctx.rejections else "normal"
            return {
                "mode": mode,
                "setpoint": 37.5,
                "power_limit": 60.0 if mode == "normal" else 100.0,
            }

    trace_file = tmp_path / "trace.jsonl"
    summary = Platform(
        hotbox,
        RunOptions(
            clock="simulated",
            seed=1,
            knowledge="memory",
            trace=trace_file,
            components={"twin": PessimistTwin(), "plan": AlwaysNormalFirst()},
        ),
    ).run(20)
    trace = read_trace(trace_file)
    rejected = [r for r in trace if r.get("rejected")]
    assert rejected and all(r["broken_rules"] == ["twin:temperature_band"] for r in rejected)
    assert "the twin predicts temperature_band is violated" in rejected[0]["explanation"]
    executed = {r["plan"] for r in trace if r.get("executed")}
    modes = {r["plan"]: r["mode"] for r in trace if r.get("planned")}
    assert executed and all(modes[p] == "boost" for p in executed)
    assert summary.stats.rejected == len(rejected)


def test_residual_model_and_drift_reach_knowledge_trace_and_chart(hotbox, tmp_path):
    trace_file = tmp_path / "trace.jsonl"
    twin = PessimistTwin(drift_at=33)  # the drift lands between two ticks
    platform = Platform(
        hotbox,
        RunOptions(
            clock="simulated",
            seed=1,
            trace=trace_file,
            knowledge=f"sqlite:{tmp_path / 'k.sqlite'}",
            components={"twin": twin},
        ),
    )
    platform.run(10)
    trace = read_trace(trace_file)
    assert any("twin_residual" in r for r in trace)
    versions = [r["twin_model_version"] for r in trace if "twin_model_version" in r]
    assert versions and versions == sorted(versions)
    drift_at = next(r["time"] for r in trace if r.get("drift"))
    # the drift started an iteration at once, not at the next tick (ticks are on 0.5 s)
    assert any(r.get("stage") == "monitor" and r["time"] == drift_at for r in trace)
    assert platform.managing.adaptation_orchestrator.interpreter.context["drifts"] == 1
    # the model was persisted and comes back into a new twin on restart
    again = PessimistTwin()
    Platform(
        hotbox,
        RunOptions(
            clock="wall",
            knowledge=f"sqlite:{tmp_path / 'k.sqlite'}",
            components={"twin": again},
        ),
    ).build()
    assert again.loaded == {"version": versions[-1], "params": {"points": versions[-1] * 50}}


class WitnessTwin(PessimistTwin):
    """Keeps what it was given next to what knowledge holds when it is asked to learn."""

    def __init__(self, inputs):
        super().__init__()
        self.inputs = inputs
        self.kb = None
        self.seen = []

    def observe(self, time, values):
        self.seen.append((dict(values), self.kb.read_values(self.inputs)))
        return super().observe(time, values)


def test_the_twin_gets_the_latest_value_of_each_input_however_it_was_stored(hotbox):
    # all inputs in each probe batch (taken from the batch); one registered by the Monitor
    # stage, never in a probe batch (read back)
    for inputs in (("temperature", "heater_power"), ("temperature", "temperature_mean")):
        twin = WitnessTwin(inputs)
        platform = Platform(
            hotbox, RunOptions(clock="simulated", seed=1, knowledge="memory",
                               components={"twin": twin})
        )
        platform.build()
        twin.kb = platform.managing.knowledge.store
        platform.run(5)
        assert len(twin.seen) > 40
        assert all(given == held and list(given) == list(inputs) for given, held in twin.seen)
        assert all(type(v) is type(h) for given, held in twin.seen for v, h in zip(
            given.values(), held.values(), strict=True
        ))
    # a refused input: the twin gets the one knowledge still holds; an int for a float: the
    # float stored
    twin = WitnessTwin(("temperature", "temperature_mean"))
    platform = Platform(
        hotbox, RunOptions(clock="simulated", seed=1, knowledge="memory", components={"twin": twin})
    )
    platform.build()
    twin.kb = platform.managing.knowledge.store
    platform.start()
    platform.scheduler.run_until(2.0)
    time = platform.clock.time
    before = platform.managing.knowledge.store.read_knowledge("temperature")
    platform.register_values({"temperature": "hot", "heater_power": 5}, time + 1.0)
    given, held = twin.seen[-1]
    assert given == held == {"temperature": before, "temperature_mean": held["temperature_mean"]}
    twin.inputs = ("temperature", "heater_power")
    platform.register_values({"temperature": 36, "heater_power": 5}, time + 2.0)
    given, held = twin.seen[-1]
    assert given == held == {"temperature": 36.0, "heater_power": 5.0}
    assert type(given["temperature"]) is float and type(given["heater_power"]) is float
    platform.stop()
