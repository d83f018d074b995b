"""The Hotbox's MAPLE-K components and its simulated managed system.

The managed system is a box with a heater under a local P-controller (set-point, gain, power
limit). The managing system watches the temperature, and when the lid is open (the temperature
falls, or is about to leave the band) it switches the controller to boost mode; when the box is
back in the band with the lid closed, it switches back to normal mode.
"""

from __future__ import annotations

import random

from rasm import Action, Anomaly, Plan

BAND = (35.0, 40.0)  # where the controller should keep the content
NORMAL = {"mode": "normal", "setpoint": 37.5, "power_limit": 60.0}
BOOST = {"mode": "boost", "setpoint": 38.5, "power_limit": 100.0}


class HotboxSimulator:
    """First-order thermal model: C dT/dt = P - k (T - T_ambient), k larger with the lid open."""

    AMBIENT = 20.0
    LOSS_CLOSED = 2.0  # W/K
    LOSS_OPEN = 12.0  # W/K
    GAIN = 25.0  # W/K, proportional gain of the local controller

    def __init__(self, scenario: dict | None = None, seed: int = 0) -> None:
        scenario = scenario or {}
        self.rng = random.Random(seed)
        self.first = float(scenario.get("first_lid_opening", 8.0))
        self.every = float(scenario.get("lid_every", 30.0))
        self.open_for = float(scenario.get("lid_open_for", 12.0))
        self.capacity = float(scenario.get("content_heat_capacity", 500.0))
        self.openings = [(float(t), float(d)) for t, d in scenario.get("openings", [])]
        # [[time, heat_capacity], ...]: the content is swapped for a lighter or heavier one
        self.content_changes = sorted(
            (float(t), float(c)) for t, c in scenario.get("content_change", []))
        self.temperature = float(scenario.get("initial_temperature", 37.5))
        self.settings = dict(NORMAL)
        self.power = 0.0

    def lid_open(self, time: float) -> bool:
        if self.openings:
            return any(start <= time < start + length for start, length in self.openings)
        if time < self.first:
            return False
        return (time - self.first) % self.every < self.open_for

    @staticmethod
    def SCENARIOS(duration):  # noqa: N802 - the name rasm.testing.scenarios looks up
        """The disturbance schedules property-based tests draw: lid openings in the run."""
        from hypothesis import strategies as st

        from rasm.testing import windows

        return st.fixed_dictionaries({"openings": windows(within=max((duration or 40) - 5, 1))})

    def step(self, time: float, dt: float) -> dict:
        while self.content_changes and self.content_changes[0][0] <= time:
            self.capacity = self.content_changes.pop(0)[1]
        lid = self.lid_open(time)
        loss = self.LOSS_OPEN if lid else self.LOSS_CLOSED
        setpoint = self.settings["setpoint"]
        # the local P-controller, with a feed-forward term for the closed-lid heat loss
        feed_forward = self.LOSS_CLOSED * (setpoint - self.AMBIENT)
        wanted = feed_forward + self.GAIN * (setpoint - self.temperature)
        self.power = min(max(wanted, 0.0), self.settings["power_limit"])
        heat_loss = loss * (self.temperature - self.AMBIENT)
        self.temperature += dt * (self.power - heat_loss) / self.capacity
        measured = self.temperature + self.rng.gauss(0.0, 0.02)
        return {
            "hotbox/sensors": {
                "temperature": round(measured, 4),
                "lid_open": lid,
                "heater_power": round(self.power, 3),
                "heater_mode": self.settings["mode"],
                "setpoint": setpoint,
            }
        }

    def apply(self, effector: str, payload: dict, time: float) -> None:
        if effector == "heater":
            for key in ("mode", "setpoint", "power_limit"):
                if key in payload:
                    self.settings[key] = payload[key]


class HotboxMonitor:
    """A sliding mean and trend of the temperature over the last second of samples."""

    WINDOW = 10

    def monitor(self, ctx):
        samples = ctx.knowledge.history("temperature", last=self.WINDOW)
        if len(samples) < 2:
            return None
        mean = sum(s.value for s in samples) / len(samples)
        span = samples[-1].time - samples[0].time
        trend = (samples[-1].value - samples[0].value) / span if span > 0 else 0.0
        return {"temperature_mean": round(mean, 4), "temperature_trend": round(trend, 4)}


class HotboxAnalyse:
    """An anomaly when the temperature comes within ``margin`` °C of leaving the safety band,
    now or ``HORIZON`` seconds ahead at its present trend, or when the heater's mode no longer
    fits (boost with the lid closed and the box warm again).

    How far inside the band the box is, is the robustness of the ``temperature_band`` property
    (properties/hotbox.rv), which the Trustworthiness Checker writes into knowledge: the
    distance in °C to the band's nearer edge, negative outside. Adapting while it is still
    above ``margin`` boosts the heater before the band is left, not after.
    """

    HORIZON = 5.0  # seconds of trend to look ahead

    def __init__(self, margin: float = 1.5) -> None:
        self.margin = margin

    def analyse(self, ctx):
        k = ctx.knowledge
        room = k.read_knowledge("robustness_temperature_band")  # °C inside the band
        mean = k.read_knowledge("temperature_mean")
        trend = k.read_knowledge("temperature_trend", 0.0)
        mode = k.read_knowledge("heater_mode", "normal")
        if room is None or mean is None:
            return None
        # in the band's lower half the room shrinks as the temperature falls
        room_ahead = room + trend * self.HORIZON
        if mode == "normal" and mean < sum(BAND) / 2 and min(room, room_ahead) < self.margin:
            return Anomaly(
                "temperature close to leaving the band",
                {"mean": mean, "room": room, "room_ahead": room_ahead, "want": "boost"},
            )
        if mode == "boost" and not k.read_knowledge("lid_open", False) and mean >= 36.5:
            return Anomaly(
                "boost no longer needed: lid closed and temperature back",
                {"mean": mean, "want": "normal"},
            )
        if mode == "boost" and mean + trend * self.HORIZON > BAND[1]:
            return Anomaly("temperature rising out of the band", {"mean": mean, "want": "normal"})
        return None


class HotboxPlan:
    """Boost or normal settings; after a rejection, a more conservative variant."""

    def plan(self, ctx):
        want = ctx.anomaly.data.get("want", "normal")
        settings = dict(BOOST if want == "boost" else NORMAL)
        if ctx.rejections:  # back off: lower the set-point and the power limit a little
            settings["setpoint"] -= 0.5 * len(ctx.rejections)
            settings["power_limit"] = min(settings["power_limit"], 70.0)
        return Plan(
            settings,
            explanation=f"switch the heater to {settings['mode']} mode "
            f"because {ctx.anomaly.reason}",
        )


class HotboxLegitimate:
    """Beyond the rules: a boost plan must not aim above the band."""

    def legitimate(self, ctx):
        if ctx.plan["setpoint"] > BAND[1]:
            return False, "set-point above the band"
        return True


class HotboxExecute:
    """One action for the heater effector."""

    def execute(self, ctx):
        return Action("heater", dict(ctx.plan.values))
