"""Forged presence over a real mosquitto, with RASM_ACTION_KEY: a dead managed process stays
lost whatever an outsider publishes on rasm/presence (unsigned heartbeats under its name, a
replay of its own signed ones, a fake managed node), and a fake node alone is never a managed
system: the fallback engages and no action is sent to nobody."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading

import pytest

from rasm import Platform, RunOptions
from rasm.comm import open_transport
from rasm.testing.servers import start_mosquitto
from tests.ros2.conftest import wait_until

from .conftest import HOTBOX, read_trace

FALLBACK = """
fallback:
  actions: {heater: {mode: normal, setpoint: 37.0, power_limit: 50}}
  when: [managed_system_lost]
  dwell: 1.0
"""
KEY = "33" * 32


def _app(tmp_path):
    app = tmp_path / "hotbox"
    skip = shutil.ignore_patterns(".rasm", "__pycache__", "app.*.yaml")
    shutil.copytree(HOTBOX, app, ignore=skip)
    (app / "app.yaml").write_text((app / "app.yaml").read_text() + FALLBACK)
    return app


class _Forger:
    """An outsider on the broker: records every presence message, and publishes forged ones
    every 0.1 s from its own thread once started."""

    def __init__(self, url):
        self.transport = open_transport(url)
        self.transport.connect()
        self.seen: list = []
        self.transport.subscribe("rasm/presence/+", lambda m: self.seen.append(m), qos=1)
        self.stop = threading.Event()
        self.sent = 0
        self.rounds = threading.Semaphore(0)  # released once per round of forgeries
        self.thread: threading.Thread | None = None

    def start(self, forgeries):
        def run():
            while not self.stop.wait(0.1):
                for topic, payload in forgeries():
                    self.transport.publish(topic, payload, qos=1)
                    self.sent += 1
                self.rounds.release()

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()

    def wait_rounds(self, n, timeout=30.0):
        """Until ``n`` rounds of forgeries went out (each 0.1 s after the last)."""
        for _ in range(n):
            assert self.rounds.acquire(timeout=timeout), "the forger stopped sending"

    def close(self):
        self.stop.set()
        if self.thread is not None:
            self.thread.join()
        self.transport.close()


def _online(node, epoch="f" * 32):
    return {"state": "online", "role": "managed", "period": 0.5, "seq": 1, "app": "hotbox",
            "epoch": epoch}


@pytest.mark.slow
def test_forged_heartbeats_neither_hide_a_dead_managed_process_nor_release_the_fallback(
    tmp_path, monkeypatch
):
    monkeypatch.setenv("RASM_ACTION_KEY", KEY)
    app = _app(tmp_path)
    broker = start_mosquitto(tmp_path)
    managed = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--role", "managed",
         "--transport", broker.url, "--duration", "60"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env=dict(os.environ),
    )
    forger = _Forger(broker.url)
    trace_file = tmp_path / "managing.jsonl"
    platform = Platform(app, RunOptions(
        role="managing",
        transport=broker.url,
        trace=trace_file,
        knowledge="memory",
    ))
    platform.build()
    engaged = threading.Event()
    platform.on_record.append(
        lambda t, r: engaged.set() if r.get("fallback") == "engaged" else None
    )
    runner = threading.Thread(target=platform.run, args=(60.0,))
    try:
        runner.start()

        distribution = platform.assembly.distribution
        wait_until(lambda: any(s == "online" for s in distribution.managed_nodes.values()),
                   what="presence to verify the managed process")
        dead = next(iter(distribution.managed_nodes))
        captured = [m.payload for m in forger.seen
                    if m.topic.endswith(dead) and m.payload.get("state") == "online"]
        assert captured and all("signature" in p for p in captured)
        managed.send_signal(signal.SIGKILL)
        assert engaged.wait(30), "the fallback did not engage"

        def forgeries():
            yield f"rasm/presence/{dead}", _online(dead)  # unsigned, under the dead node's name
            yield "rasm/presence/hotbox-managed-1", _online("hotbox-managed-1")  # a fake node
            for payload in captured:  # its own signed heartbeats, replayed
                yield f"rasm/presence/{dead}", payload

        forger.start(forgeries)
        # 4 s of forgeries, long past the dwell (1 s) and the tracker's timeout (1.5 s)
        forger.wait_rounds(40)
        assert not platform.assembly.distribution.managed_online
        assert platform.assembly.distribution.tracker.refused > 30
    finally:
        forger.close()
        if managed.poll() is None:
            managed.kill()
        managed.wait(10)
        platform.request_stop()
        runner.join(30)
        broker.stop()
    trace = read_trace(trace_file)
    assert [r["fallback"] for r in trace if "fallback" in r] == ["engaged"]
    sent = [r for r in trace if r.get("executed")]
    killed = next(r["time"] for r in trace if r.get("fallback") == "engaged")
    assert not [r for r in sent if r["time"] >= killed]


@pytest.mark.slow
def test_a_fake_managed_node_is_no_managed_system(tmp_path, monkeypatch):
    monkeypatch.setenv("RASM_ACTION_KEY", KEY)
    app = _app(tmp_path)
    broker = start_mosquitto(tmp_path)
    forger = _Forger(broker.url)
    # no managed process at all: only a fake one, unsigned, heartbeating from the start
    forger.start(lambda: [("rasm/presence/hotbox-managed-7", _online("hotbox-managed-7"))])
    trace_file = tmp_path / "managing.jsonl"
    try:
        platform = Platform(app, RunOptions(
            role="managing",
            transport=broker.url,
            trace=trace_file,
            knowledge="memory",
        ))
        platform.run(6.0)
    finally:
        forger.close()
        broker.stop()
    trace = read_trace(trace_file)
    assert [r["fallback"] for r in trace if "fallback" in r] == ["engaged"]
    assert not [r for r in trace if r.get("executed")]
    distribution = platform.assembly.distribution
    assert distribution.tracker.refused > 10 and not distribution.managed_nodes
