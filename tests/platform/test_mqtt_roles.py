"""Managed and managing Hotbox in two processes over a real mosquitto broker, adapting."""

from __future__ import annotations

import pytest

from rasm import Platform, RunOptions
from rasm.testing.servers import start_mosquitto

from .conftest import read_trace, start_managed


@pytest.mark.slow
def test_managed_and_managing_processes_adapt_over_mqtt(hotbox, tmp_path):
    broker = start_mosquitto(tmp_path)
    managed = start_managed(broker, tmp_path, duration=14)
    try:
        trace_file = tmp_path / "managing.jsonl"
        summary = Platform(
            hotbox, RunOptions(role="managing", transport=broker.url, trace=trace_file,
                               knowledge="memory")
        ).run(12.0)
        managed_out, _ = managed.communicate(timeout=30)
    finally:
        if managed.poll() is None:
            managed.kill()
        broker.stop()
    assert managed.returncode == 0, managed_out
    trace = read_trace(trace_file)
    # the probes crossed the broker into the managing system's knowledge ...
    assert sum("temperature" in r for r in trace) > 50
    # ... the lid opening (8 s into the managed process) was answered by an executed action ...
    assert summary.stats.executed >= 1
    # ... and the action crossed back: the managed system reported boost mode afterwards
    executed_at = next(r["time"] for r in trace if r.get("executed"))
    assert any(r.get("heater_mode") == "boost" for r in trace if r["time"] > executed_at)
    assert summary.verdicts["timely_adaptation"] == "satisfied"
