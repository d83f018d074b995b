"""The Hotbox's twin and simulator for the tests, and synthetic runs of a box with known
parameters driven by a plan schedule that excites it (lid openings, set-point steps)."""

from __future__ import annotations

import importlib.util
import random
import sys
from pathlib import Path
from typing import Any

APP = Path(__file__).resolve().parents[2] / "examples" / "hotbox"


def _module(name: str) -> Any:
    qualified = f"rasm_app_hotbox.{name}"  # the name the runtime gives it (load_component)
    if qualified not in sys.modules:
        spec = importlib.util.spec_from_file_location(qualified, APP / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[qualified] = module
        spec.loader.exec_module(module)
    return sys.modules[qualified]


twin_module = _module("twin")
components = _module("components")
HotboxTwin = twin_module.HotboxTwin


def box(capacity: float, loss_closed: float, loss_open: float) -> type:
    """A HotboxSimulator class with these physical parameters (the controller unchanged) and
    the scenario key ``content_change: [[time, capacity], ...]``."""

    class Box(components.HotboxSimulator):
        LOSS_OPEN = loss_open

        def __init__(self, scenario: dict | None = None, seed: int = 0) -> None:
            scenario = {"content_heat_capacity": capacity, **(scenario or {})}
            super().__init__(scenario, seed)
            changes = scenario.get("content_change", [])
            self.changes = sorted((float(t), float(c)) for t, c in changes)
            self.loss_closed = loss_closed
            self.noise = 0.02  # the Hotbox's sensor

        def step(self, time: float, dt: float) -> dict:
            while self.changes and time >= self.changes[0][0]:
                self.capacity = self.changes.pop(0)[1]
            # the plant's closed-lid loss may differ from the controller's feed-forward (2 W/K)
            lid = self.lid_open(time)
            loss = self.LOSS_OPEN if lid else self.loss_closed
            feed_forward = self.LOSS_CLOSED * (self.settings["setpoint"] - self.AMBIENT)
            wanted = feed_forward + self.GAIN * (self.settings["setpoint"] - self.temperature)
            self.power = min(max(wanted, 0.0), self.settings["power_limit"])
            self.temperature += (
                dt * (self.power - loss * (self.temperature - self.AMBIENT)) / self.capacity
            )
            measured = self.temperature + self.rng.gauss(0.0, self.noise)
            return {
                "hotbox/sensors": {
                    "temperature": round(measured, 4),
                    "lid_open": lid,
                    "heater_power": round(self.power, 3),
                    "heater_mode": self.settings["mode"],
                    "setpoint": self.settings["setpoint"],
                }
            }

    return Box


def drive(
    twin: Any,
    simulator: Any,
    duration: float,
    *,
    seed: int = 0,
    noise: float = 0.02,
    dt: float = 0.1,
    plans_every: float = 10.0,
) -> list[tuple[float, Any]]:
    """Run ``simulator`` for ``duration`` s, feeding ``twin`` as the runtime does (one call per
    probe message); every ``plans_every`` s a random plan (mode, set-point, power limit).
    Returns the ``(time, update)`` pairs that were not None."""
    simulator.noise = noise
    rng = random.Random(seed)
    updates = []
    for n in range(1, int(round(duration / dt)) + 1):
        time = round(n * dt, 9)
        if time % plans_every < dt / 2:
            mode = rng.choice(["normal", "boost"])
            simulator.apply(
                "heater",
                {
                    "mode": mode,
                    "setpoint": rng.uniform(36.0, 39.0),
                    "power_limit": 60.0 if mode == "normal" else 100.0,
                },
                time,
            )
        signals = simulator.step(time, dt)["hotbox/sensors"]
        update = twin.observe(time, {k: signals[k] for k in twin.inputs})
        if update is not None:
            updates.append((time, update))
    return updates
