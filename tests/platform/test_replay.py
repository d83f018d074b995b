"""Replayed signed actions over a real mosquitto, with real `rasm run` processes on both sides.

An action captured on the effector topic in one run and republished into a freshly started
managed process is refused (it was bound to the previous incarnation); a managing process
restarted while the managed one keeps running is obeyed (its new run starts a new sequence).
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import time
from pathlib import Path

import paho.mqtt.client as paho
import pytest

from rasm import Platform, RunOptions
from rasm.comm import BoundSigner, MqttTransport, Presence, verify
from rasm.loop import MEASURED_KEYS
from rasm.testing.servers import start_mosquitto

from .conftest import HOTBOX

ACTION_KEY = "c3" * 16
# the lid opens 2 s into the managed process's run, for 4 s: boost, then back to normal
SCENARIO = json.dumps({"openings": [[2.0, 4.0]]})


def rasm_run(broker, cwd: Path, role: str, duration: float, *extra: str) -> subprocess.Popen:
    cwd.mkdir(parents=True, exist_ok=True)
    return subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--role", role]
        + ["--transport", broker.url, "--duration", str(duration), *extra],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "RASM_ACTION_KEY": ACTION_KEY},
    )


class Bus:
    """What the test sees on the broker, in the broker's order (one connection): the heater's
    mode in each sensor reading, the plans on the managing side's trace, the nodes starting."""

    def __init__(self, broker) -> None:
        self.events: queue.Queue[tuple[str, str]] = queue.Queue()
        self.transport = MqttTransport(broker.url)
        self.transport.connect()
        self.transport.subscribe(
            "hotbox/sensors",
            lambda m: self.events.put(("mode", m.payload.get("heater_mode"))),
            qos=1,
        )
        self.transport.subscribe(
            "rasm/trace",
            lambda m: m.payload.get("planned") and self.events.put(("plan", m.payload["plan"])),
            qos=1,
        )
        self.transport.subscribe(
            "rasm/presence/+",
            lambda m: (
                m.payload.get("state") == "online"
                and m.payload.get("seq") == 0
                and self.events.put(("node", m.topic.rsplit("/", 1)[-1]))
            ),
            qos=1,
        )

    def wait_for(self, kind: str, value: str, timeout: float = 60.0) -> list[tuple[str, str]]:
        """Every event up to the first ``(kind, value)``; fails after ``timeout`` seconds."""
        seen: list[tuple[str, str]] = []
        deadline = time.monotonic() + timeout
        while (kind, value) not in seen:
            seen.append(self.events.get(timeout=max(0.0, deadline - time.monotonic())))
        return seen

    def close(self) -> None:
        self.transport.close()


class Capture:
    """Raw bytes of every message on the effector topic, as an attacker on the bus keeps them."""

    def __init__(self, broker, topic: str) -> None:
        self.topic = topic
        self.messages: list[bytes] = []
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2)
        self.client.on_message = lambda client, userdata, msg: self.messages.append(msg.payload)
        self.client.connect(broker.host, broker.port)
        self.client.loop_start()
        self.client.subscribe(topic, qos=1)[1]

    def replay(self) -> int:
        """Publish every captured message again, byte for byte; returns how many."""
        payloads = list(self.messages)  # what is replayed is captured again: not replayed twice
        for payload in payloads:
            self.client.publish(self.topic, payload, qos=1).wait_for_publish(10)
        return len(payloads)

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def _finish(process: subprocess.Popen, timeout: float = 60.0) -> str:
    try:
        out, _ = process.communicate(timeout=timeout)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    return out


@pytest.mark.slow
def test_an_action_replayed_into_a_restarted_managed_process_is_refused(tmp_path):
    broker = start_mosquitto(tmp_path)
    bus, capture = Bus(broker), Capture(broker, "hotbox/heater")
    processes: list[subprocess.Popen] = []
    try:
        # run 1: both halves; the managed process applies the signed boost action
        managed = rasm_run(broker, tmp_path / "managed", "managed", 60, "--scenario", SCENARIO)
        managing = rasm_run(broker, tmp_path / "managing", "managing", 60)
        processes += [managed, managing]
        bus.wait_for("mode", "boost")
        assert capture.messages, "the boost action crossed the bus, and was captured"
        for process in (managing, managed):  # both gone: no managing process from here on
            process.kill()
            process.wait(10)

        # run 2: a fresh managed process alone; the captured actions are published into it
        fresh = rasm_run(broker, tmp_path / "managed", "managed", 8)
        processes.append(fresh)
        bus.wait_for("node", f"hotbox-managed-{fresh.pid}")
        after = bus.wait_for("mode", "normal")  # it runs (and so listens on its effector topic)
        replayed = capture.replay()
        out = _finish(fresh)
        while not bus.events.empty():
            after.append(bus.events.get())
    finally:
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait(10)
        capture.close()
        bus.close()
        broker.stop()
    assert fresh.returncode == 0, out
    assert f"'actions refused by the effector gate': {replayed}" in out, out
    assert "signed for another incarnation" in out
    assert ("mode", "boost") not in after  # the heater never left normal mode


@pytest.mark.slow
def test_a_restarted_managing_process_is_obeyed(tmp_path):
    broker = start_mosquitto(tmp_path)
    bus = Bus(broker)
    processes: list[subprocess.Popen] = []
    try:
        # until the test stops it (SIGTERM, once the second managing run's action is applied)
        managed = rasm_run(broker, tmp_path / "managed", "managed", 120, "--scenario", SCENARIO)
        first = rasm_run(broker, tmp_path / "managing", "managing", 60)
        processes += [managed, first]
        before = bus.wait_for("mode", "boost")  # the first managing run's action was applied
        first.kill()  # a crash: the managed process keeps running, with what it applied
        first.wait(10)
        # the same folder (its knowledge restored), a new run
        second = rasm_run(broker, tmp_path / "managing", "managing", 60)
        processes.append(second)
        bus.wait_for("node", f"hotbox-managing-{second.pid}")
        after = bus.wait_for("mode", "normal")  # the restarted process's action was applied
        second.terminate()
        second.wait(10)
        managed.terminate()  # stops in order: summary printed, exit code by the verdicts
        out = _finish(managed)
    finally:
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait(10)
        bus.close()
        broker.stop()
    assert managed.returncode == 0, out
    assert "actions refused by the effector gate" not in out, out
    # plan ids never repeat across runs: each run's start with its own run id
    plans = [value for kind, value in before if kind == "plan"]
    new_plans = [value for kind, value in after if kind == "plan"]
    assert plans and new_plans
    assert len({plan.split("-p")[0] for plan in plans + new_plans}) == 2
    assert not set(plans) & set(new_plans)


def test_no_action_is_sent_before_a_managed_process_announced_its_epoch(
    hotbox, tmp_path, monkeypatch, caplog
):
    """Fail closed: the checker refuses, with the reason in the trace, an action it cannot bind;
    once a managed process's epoch is announced, the next action is bound to it."""
    broker = start_mosquitto(tmp_path)
    monkeypatch.setenv("RASM_ACTION_KEY", ACTION_KEY)
    platform = Platform(hotbox, RunOptions(role="managing", transport=broker.url,
                                           knowledge="memory"))
    platform.build()
    feeder = MqttTransport(broker.url)
    feeder.connect()
    sent: queue.Queue[dict] = queue.Queue()
    feeder.subscribe("hotbox/heater", lambda m: sent.put(m.payload), qos=1)
    cold = {"temperature": 30.0, "lid_open": True, "heater_power": 60.0}
    reading = {**cold, "heater_mode": "normal", "setpoint": 37.5}
    # with the key only signed heartbeats bound to the managing process count
    presence = Presence(
        feeder, "hotbox-managed-x", role="managed", info={"app": "hotbox", "epoch": "e-x"},
        signer=BoundSigner(bytes.fromhex(ACTION_KEY)),
        receivers=lambda: [platform.assembly.distribution.epoch],
    )
    refusals: list[dict] = []

    def watch(time: float, record: dict) -> None:
        if record.get("dropped") and not refusals:
            refusals.append(record)
            presence.start()  # a managed process announces itself (and its epoch)
        if record.get("executed"):
            platform.scheduler.stop()

    platform.on_record.append(watch)
    platform.scheduler.every(0.1, lambda: feeder.publish("hotbox/sensors", reading))
    try:
        summary = platform.run(60.0)
        action = sent.get(timeout=10)
    finally:
        presence.stop()
        feeder.close()
        broker.stop()
    assert refusals[0]["explanation"] == (
        "effector unreachable: not sent: no managed process has announced its epoch yet, and a "
        "signed action is bound to the epoch of the process that applies it"
    )
    assert summary.stats.executed == 1
    warnings = [r.message for r in caplog.records if "announced its epoch" in r.message]
    assert warnings == ["no managed process has announced its epoch: actions are not sent"]
    binding = action["binding"]
    assert binding["epochs"] == ["e-x"] and binding["topic"] == "hotbox/heater"
    run = platform.assembly.distribution.run
    assert binding["run"] == run and binding["seq"] == 1  # nothing signed before
    assert action["plan"].startswith(f"{run}-p")
    assert verify(action, bytes.fromhex(ACTION_KEY))


def test_seeded_simulated_runs_with_signed_actions_stay_reproducible(tmp_path, monkeypatch):
    """The random run ids and epochs of signing never reach a simulated run's trace: two runs
    with the same seed write the same records (stage durations aside, as they are wall-clock),
    with plan ids p1, p2, …"""
    from rasm.cli import main

    monkeypatch.setenv("RASM_ACTION_KEY", ACTION_KEY)
    monkeypatch.chdir(tmp_path)
    traces = []
    for run in ("a", "b"):
        args = ["run", str(HOTBOX), "--clock", "simulated", "--seed", "7", "--duration", "20"]
        assert main([*args, "--trace", f"{run}.jsonl"]) == 0
        records = [json.loads(line) for line in Path(f"{run}.jsonl").read_text().splitlines()]
        traces.append([{k: v for k, v in r.items() if k not in MEASURED_KEYS} for r in records])
    assert traces[0] == traces[1]
    plans = [r["plan"] for r in traces[0] if r.get("planned")]
    assert plans and plans == [f"p{n}" for n in range(1, len(plans) + 1)]
    # the signed actions went through the gate: the simulator reports the mode they set
    assert any(r.get("heater_mode") == "boost" for r in traces[0])
