"""The loop goes on through a broker restart, and data flows again once the broker is back."""

from __future__ import annotations

import threading

import pytest

from rasm import Platform, RunOptions
from rasm.testing.servers import start_mosquitto

from .conftest import read_trace, start_managed


@pytest.mark.slow
def test_the_loop_continues_across_a_broker_restart(hotbox, tmp_path):
    broker = start_mosquitto(tmp_path)
    managed = start_managed(broker, tmp_path, duration=40)
    trace_file = tmp_path / "managing.jsonl"
    platform = Platform(
        hotbox, RunOptions(role="managing", transport=broker.url, trace=trace_file,
                           knowledge="memory")
    )
    platform.build()
    restarted_at: list[float] = []
    flowing_again = threading.Event()
    seen = {"before": 0}

    def restart_broker():
        broker.restart()  # stop, then a fresh broker on the same port
        restarted_at.append(platform.clock.time)

    def watch(time, record):
        if "temperature" not in record:
            return
        if not restarted_at:
            seen["before"] += 1
            if seen["before"] == 20:  # two seconds of sensor data crossed the broker
                threading.Thread(target=restart_broker).start()
        elif time > restarted_at[0] and not flowing_again.is_set():
            flowing_again.set()  # the managed side's data reaches us through the new broker

    platform.on_record.append(watch)
    runner = threading.Thread(target=platform.run, args=(20.0,))
    try:
        runner.start()
        assert flowing_again.wait(30), "no data after the broker restart"
        runner.join(40)
    finally:
        if managed.poll() is None:
            managed.kill()
        managed.wait(10)
        broker.stop()
    trace = read_trace(trace_file)
    after = [r for r in trace if r["time"] > restarted_at[0]]
    # the loop kept its rhythm through the outage and after it
    assert sum(r.get("stage") == "monitor" for r in after) >= 5
    assert sum("temperature" in r for r in after) >= 10
    assert platform.assembly.transport.stats.as_dict()["reconnects"] >= 1
