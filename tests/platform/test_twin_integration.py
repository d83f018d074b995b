"""How the runtime uses a digital twin: residual and model in knowledge, drift starts an
iteration, Legitimate rejects plans the twin predicts will break a property."""

from __future__ import annotations

from dataclasses import dataclass

from rasm.platform.runtime import Platform

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
        clock="simulated",
        seed=1,
        knowledge="memory",
        trace=trace_file,
        components={"twin": PessimistTwin(), "plan": AlwaysNormalFirst()},
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
        clock="simulated",
        seed=1,
        trace=trace_file,
        knowledge=f"sqlite:{tmp_path / 'k.sqlite'}",
        components={"twin": twin},
    )
    platform.run(10)
    trace = read_trace(trace_file)
    assert any("twin_residual" in r for r in trace)
    versions = [r["twin_model_version"] for r in trace if "twin_model_version" in r]
    assert versions and versions == sorted(versions)
    drift_at = next(r["time"] for r in trace if r.get("drift"))
    # the drift started an iteration at once, not at the next tick (ticks are on 0.5 s)
    assert any(r.get("stage") == "monitor" and r["time"] == drift_at for r in trace)
    assert platform.ao.interpreter.context["drifts"] == 1
    # the model was persisted and comes back into a new twin on restart
    again = PessimistTwin()
    Platform(
        hotbox,
        clock="wall",
        knowledge=f"sqlite:{tmp_path / 'k.sqlite'}",
        components={"twin": again},
    ).build()
    assert again.loaded == {"version": versions[-1], "params": {"points": versions[-1] * 50}}
