"""A managed system really lost: the Hotbox's managed process, killed, over a real mosquitto.
The managing side's fallback engages as soon as presence reports the node gone (its last will),
and tries its action, which the Trustworthiness Checker refuses while nobody is there."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
import time

from rasm import Platform, RunOptions
from rasm.testing.servers import start_mosquitto

from .conftest import HOTBOX, read_trace

FALLBACK = """
fallback:
  actions: {heater: {mode: normal, setpoint: 37.0, power_limit: 50}}
  when: [managed_system_lost]
  dwell: 1.0
"""


def test_a_killed_managed_process_engages_the_fallback(tmp_path):
    app = tmp_path / "hotbox"
    skip = shutil.ignore_patterns(".rasm", "__pycache__", "app.*.yaml")
    shutil.copytree(HOTBOX, app, ignore=skip)
    (app / "app.yaml").write_text((app / "app.yaml").read_text() + FALLBACK)
    broker = start_mosquitto(tmp_path)
    managed = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--role", "managed",
         "--transport", broker.url, "--duration", "60"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env=dict(os.environ),
    )
    trace_file = tmp_path / "managing.jsonl"
    platform = Platform(app, RunOptions(
        role="managing",
        transport=broker.url,
        trace=trace_file,
        knowledge="memory",
    ))
    platform.build()
    heard, engaged = threading.Event(), threading.Event()
    killed_at: list[float] = []

    def watch(when, record):
        if "temperature" in record and not heard.is_set():
            heard.set()
        if record.get("fallback") == "engaged":
            engaged.set()
            platform.scheduler.stop()

    platform.on_record.append(watch)
    runner = threading.Thread(target=platform.run, args=(40.0,))
    try:
        runner.start()
        assert heard.wait(30), "no reading crossed the broker"
        deadline = time.monotonic() + 30
        while not platform.assembly.distribution.managed_nodes and time.monotonic() < deadline:
            time.sleep(0.05)  # presence has not announced the managed node yet
        assert platform.assembly.distribution.managed_online, "presence never saw the managed node"
        managed.send_signal(signal.SIGKILL)
        killed_at.append(time.monotonic())
        assert engaged.wait(30), "the fallback did not engage"
        reaction = time.monotonic() - killed_at[0]
        runner.join(30)
    finally:
        if managed.poll() is None:
            managed.kill()
        managed.wait(10)
        platform.request_stop()
        runner.join(30)
        broker.stop()
    trace = read_trace(trace_file)
    switch = next(r for r in trace if r.get("fallback") == "engaged")
    assert switch["explanation"] == "fallback engaged: managed system lost"
    # a live run's plan ids start with the run's id: <run>-f1
    attempts = [r for r in trace if str(r.get("plan", "")).endswith("-f1")
                and ("dropped" in r or "executed" in r)]
    assert attempts and attempts[0].get("dropped")
    assert attempts[0]["explanation"] == "the managed system is offline"
    assert reaction < 10  # the broker publishes the killed node's last will at once
