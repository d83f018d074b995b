"""The monitors of monitors/ are bound to the running orchestrator and refuse bad steps."""

from __future__ import annotations

import shutil

from rasm import Platform, RunOptions
from rasm.platform.manifest import load_manifest
from rasm.resources import platform_chart

from .conftest import HOTBOX, read_trace


class RuleBreaker:
    """Always plans something the rules reject (power above the heater's rating)."""

    def plan(self, ctx):
        return {"mode": "boost", "setpoint": 38.0, "power_limit": 150.0}


def broken_app(tmp_path):
    """The Hotbox with an orchestrator chart that executes rejected plans."""
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    chart = platform_chart("adaptation_orchestrator").read_text()
    needle = "target: planning\n                event: rejected"
    assert needle in chart
    (app / "broken_orchestrator.yaml").write_text(
        chart.replace(needle, "target: executing\n                event: rejected")
    )
    manifest = (app / "app.yaml").read_text()
    (app / "app.yaml").write_text(
        manifest + "statecharts:\n  adaptation_orchestrator: broken_orchestrator.yaml\n"
    )
    return load_manifest(app)


def test_the_platform_monitors_refuse_a_broken_orchestrator_step(tmp_path):
    trace_file = tmp_path / "trace.jsonl"
    platform = Platform(
        broken_app(tmp_path),
        RunOptions(
            clock="simulated",
            seed=1,
            knowledge="memory",
            trace=trace_file,
            components={"plan": RuleBreaker()},
        ),
    )
    summary = platform.run(20)
    trace = read_trace(trace_file)
    assert summary.stats.rejected >= 1
    # the broken transition was refused by the monitor every time: nothing was executed
    assert not any(r.get("executed") for r in trace)
    assert platform.managing.adaptation_orchestrator.step_failures >= summary.stats.rejected
    # and the loop went on: every tick still started an iteration
    assert summary.stats.iterations == 40


def test_the_shipped_orchestrator_passes_the_monitors(hotbox):
    platform = Platform(
        hotbox, RunOptions(clock="simulated", seed=1, knowledge="memory",
                           components={"plan": RuleBreaker()})
    )
    summary = platform.run(20)
    assert summary.stats.rejected >= 1 and summary.stats.cancelled >= 1
    assert platform.managing.adaptation_orchestrator.step_failures == 0
