"""An app whose rules read plan fields runs: rules that only disagree on plans the planner need
not choose do not conflict (SPEC section 7), with the app's ``components.plan.produces`` as the
plan fields. Before, ``rasm run`` refused this app for a conflict no context has."""

from __future__ import annotations

import json
from pathlib import Path

from rasm.cli import main

RULES = """variables:
  battery: {type: real, min: 0, max: 100}
  dock:    {type: bool}
  speed:   {type: real, min: 0, max: 1}
rules:
  - name: dock_when_low
    when: battery < 10
    require: dock
  - name: keep_moving
    when: not dock
    require: speed >= 0.2
"""

COMPONENTS = '''
from rasm.platform.components import Action, Anomaly, Plan


class Battery:
    """Drains 10 % a second from 50 %: low (under 10 %) from t = 4.1 s on."""

    def __init__(self, scenario=None, seed=0):
        self.commands = []

    def step(self, time, dt):
        return {"robot/battery": {"battery": max(0.0, 50.0 - 10.0 * time)}}

    def apply(self, effector, payload, time):
        self.commands.append((time, dict(payload)))


class Watch:
    def monitor(self, ctx):
        return None


def low(ctx):
    return ctx.knowledge.read_knowledge("battery", 100.0) < 10


class WhenLowChanges:
    """An anomaly when the battery becomes low (or not): drive, or go and dock."""

    def __init__(self):
        self.was = None

    def analyse(self, ctx):
        now = low(ctx)
        changed, self.was = now != self.was, now
        return Anomaly("dock" if now else "drive") if changed else None


class DockWhenLow:
    def plan(self, ctx):
        return Plan({"dock": low(ctx), "speed": 0.0 if low(ctx) else 0.5})


class Send:
    def execute(self, ctx):
        return Action("drive", dict(ctx.plan.values))
'''

MANIFEST = """
name: docking
components:
  monitor: components:Watch
  analyse: components:WhenLowChanges
  plan:
    component: components:DockWhenLow
    produces: {dock: bool, speed: float}
  execute: components:Send
managed_system:
  simulator: components:Battery
  period: 0.5
probes:
  - topic: robot/battery
    signals:
      battery: {type: float, min: 0, max: 100}
effectors:
  drive:
    topic: robot/drive
rules: rules/dock.yaml
transport: local
knowledge: memory
timing: "off"
loop:
  period: 0.5
"""


def write_app(folder: Path) -> Path:
    (folder / "rules").mkdir(parents=True)
    (folder / "rules" / "dock.yaml").write_text(RULES)
    (folder / "components.py").write_text(COMPONENTS)
    (folder / "app.yaml").write_text(MANIFEST)
    return folder


def test_the_app_runs_and_docks_when_low(tmp_path, capsys):
    app = write_app(tmp_path / "docking")
    trace = tmp_path / "trace.jsonl"
    code = main(["run", str(app), "--clock", "simulated", "--duration", "8",
                 "--trace", str(trace)])
    out, err = capsys.readouterr()
    assert code == 0, err
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    assert not [r for r in records if r.get("rejected")]
    legitimate = {r["plan"]: r["time"] for r in records if r.get("legitimate")}
    executed = {r["plan"] for r in records if r.get("executed")}
    assert set(legitimate) == executed == {"p1", "p2"}
    # p1 drives ({dock: false, speed: 0.5}); p2, at low battery, is {dock: true, speed: 0}:
    # both rules allow it, and the run did not refuse the rules
    planned = {r["plan"]: (r["dock"], r["speed"]) for r in records if r.get("planned")}
    assert planned == {"p1": (False, 0.5), "p2": (True, 0.0)}
    assert legitimate["p2"] > 4.0


def test_verify_rules_judges_the_app_with_its_plan_fields(tmp_path, capsys):
    app = write_app(tmp_path / "docking")
    assert main(["verify-rules", str(app)]) == 0
    out = capsys.readouterr().out
    assert "plan fields (chosen by the planner): dock, speed" in out
    assert "1 rule," not in out and "2 rules, consistent: 0 unsatisfiable, 0 conflicts" in out
    # the file alone has no plan field: every variable is context, and the rules conflict
    assert main(["verify-rules", str(app / "rules" / "dock.yaml")]) == 1
    out = capsys.readouterr().out
    assert "2 rules, inconsistent: 0 unsatisfiable, 1 conflict, 0 redundant" in out
