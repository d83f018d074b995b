"""Logging and Tracking: the platform's log records reach the file and bus sinks while it runs."""

from __future__ import annotations

import json

from rasm import Platform, RunOptions


def test_log_sinks_file_and_bus(hotbox, tmp_path):
    log_file = tmp_path / "rasm.log"
    hotbox.logging = {"level": "info", "sinks": [f"file:{log_file}", "bus:rasm/log"]}
    platform = Platform(hotbox, RunOptions(clock="simulated", knowledge="memory"))
    platform.build()
    published = []
    platform.assembly.transport.subscribe(
        "rasm/log", lambda message: published.append(message.payload)
    )

    class Crashing:
        def plan(self, ctx):
            raise RuntimeError("planner bug 42")

    platform.managing.adaptation_orchestrator.components["plan"] = Crashing()
    platform.run(12)
    text = log_file.read_text()
    assert "plan stage failed: RuntimeError: planner bug 42" in text
    assert any("planner bug 42" in p["message"] and p["level"] == "ERROR" for p in published)
    assert platform.assembly.logging_and_tracking.counts["ERROR"] >= 1
    # the sinks are detached at termination
    assert not platform.assembly.logging_and_tracking.handlers
    json.dumps(published)  # bus payloads are plain JSON

