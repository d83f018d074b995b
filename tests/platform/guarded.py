"""A small robot app whose actions a veto property guards, written into a test's folder.

The simulator publishes ``speed`` (fast during the scenario's ``fast`` windows) and ``x`` (a
float without a declared range: 1e308 at the scenario's ``overflow_at`` times, else 1.0) every
``period`` seconds, and nothing during the scenario's ``silent`` windows. Every ``every``-th
loop iteration has an anomaly and plans one action for the ``motor`` effector, so actions are
tried all along the run. ``properties/robot.rv`` holds the veto property ``slow`` and
``budget``, a ``sum`` over a window of ``x`` that two readings of 1e308 overflow. ``extra``
adds properties (and their inputs) to that file.
"""

from __future__ import annotations

from pathlib import Path

COMPONENTS = '''
from rasm.platform.components import Action, Anomaly, Plan


class GuardedSimulator:
    def __init__(self, scenario=None, seed=0):
        scenario = scenario or {}
        self.fast = [tuple(w) for w in scenario.get("fast", [])]
        self.overflow = [float(t) for t in scenario.get("overflow_at", [])]
        self.silent = [tuple(w) for w in scenario.get("silent", [])]
        self.commands = []

    def step(self, time, dt):
        if any(a <= time < b for a, b in self.silent):
            return {}  # the robot is gone: nothing comes
        speed = 2.0 if any(a <= time < b for a, b in self.fast) else 0.5
        x = 1e308 if any(abs(time - t) < dt / 2 for t in self.overflow) else 1.0
        return {"robot/sensors": {"speed": speed, "x": x}}

    def apply(self, effector, payload, time):
        self.commands.append((time, dict(payload)))


class Watch:
    def monitor(self, ctx):
        return None


class Every:
    EVERY = EVERY_N

    def analyse(self, ctx):
        return Anomaly("time to act") if ctx.iteration % self.EVERY == 0 else None


class Level:
    def plan(self, ctx):
        return Plan({"level": 1}, explanation="move on")


class Send:
    def execute(self, ctx):
        return Action("motor", dict(ctx.plan.values))
'''

MANIFEST = """
name: guarded
components:
  monitor: components:Watch
  analyse: components:Every
  plan: components:Level
  execute: components:Send
managed_system:
  simulator: components:GuardedSimulator
  period: {period}
probes:
  - topic: robot/sensors
{staleness}    signals:
      speed: {{type: float, min: 0, max: 10}}
      x: {{type: float}}
{more_signals}
effectors:
  motor:
    topic: robot/motor
properties:
  - properties/robot.rv
transport: local
knowledge: memory
timing: "off"
duration: 30
loop:
  period: {period}
  stage_budget: 0.5
trustworthiness:
  veto_properties: [{veto}]
"""

PROPERTIES = """
input speed: float
input x: float
{inputs}
# the veto property: no action while the robot is fast
property slow:
    always (speed <= 1.0)

# a sum over a window of a float without a declared range: two readings of 1e308 overflow it
property budget:
    always (sum[0, {window}](x) <= 1e300)
{extra}
"""


def write_guarded_app(
    folder: Path,
    *,
    period: float = 0.5,
    window: str = "5s",
    every: int = 1,
    veto: tuple[str, ...] = ("slow",),
    signals: dict[str, str] | None = None,
    inputs: str = "",
    extra: str = "",
    staleness: float | None = None,
) -> Path:
    """Write the app into ``folder``; ``signals`` adds probe signals (name -> type) the
    simulator never publishes; ``staleness`` is the probe's. Returns the folder."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "properties").mkdir(exist_ok=True)
    more = "".join(f"      {name}: {{type: {kind}}}\n" for name, kind in (signals or {}).items())
    (folder / "app.yaml").write_text(
        MANIFEST.format(
            period=period, veto=", ".join(veto), more_signals=more.rstrip("\n"),
            staleness=f"    staleness: {staleness}\n" if staleness is not None else "",
        )
    )
    (folder / "components.py").write_text(COMPONENTS.replace("EVERY_N", str(every)))
    (folder / "properties" / "robot.rv").write_text(
        PROPERTIES.format(window=window, inputs=inputs, extra=extra)
    )
    return folder
