"""The runtime over a real broker: a killed managed process suspends the loop, actions are
signed end to end, signed rule updates are applied only when consistent, timing is written."""

from __future__ import annotations

import json
import signal
import threading

import pytest

from rasm import Platform, RunOptions
from rasm.comm import BoundSigner, PresenceTracker, open_transport
from rasm.testing.servers import start_mosquitto

from .conftest import HOTBOX, read_trace, start_managed

ACTION_KEY = "a1" * 16
UPDATE_KEY = "b2" * 16


@pytest.mark.slow
def test_killed_managed_process_suspends_the_loop_and_signed_actions_flow(
    hotbox, tmp_path, monkeypatch
):
    monkeypatch.setenv("RASM_ACTION_KEY", ACTION_KEY)
    broker = start_mosquitto(tmp_path)
    managed = start_managed(broker, tmp_path, duration=60, env={"RASM_ACTION_KEY": ACTION_KEY})
    trace_file = tmp_path / "managing.jsonl"
    platform = Platform(
        hotbox, RunOptions(role="managing", transport=broker.url, trace=trace_file,
                           knowledge="memory")
    )
    platform.build()
    boosted, suspended = threading.Event(), threading.Event()

    def watch(time, record):
        if record.get("heater_mode") == "boost" and not boosted.is_set():
            boosted.set()  # the signed action reached the managed process and was applied
            managed.send_signal(signal.SIGKILL)

    def on_enter_suspended():  # the orchestrator's chart entered `suspended`
        # (a managed process slow to start is lost until its first heartbeat: only a
        # suspension after the action, when it was killed, ends the test)
        if boosted.is_set():
            suspended.set()
            platform.scheduler.stop()

    platform.on_record.append(watch)
    platform.managing.adaptation_orchestrator.on_enter_suspended = on_enter_suspended
    runner = threading.Thread(target=platform.run, args=(40.0,))
    try:
        runner.start()
        runner.join(60)
    finally:
        if managed.poll() is None:
            managed.kill()
        managed.wait(10)
        broker.stop()
    assert boosted.is_set(), "no signed action was applied by the managed process"
    assert suspended.is_set(), "the loop did not notice the managed process died"
    assert list(platform.assembly.state_manager.nodes.values()) == ["offline"]
    trace = read_trace(trace_file)
    assert any(r.get("executed") for r in trace)


def test_signed_rule_updates_and_timing(hotbox, tmp_path, monkeypatch):
    monkeypatch.setenv("RASM_UPDATE_KEY", UPDATE_KEY)
    broker = start_mosquitto(tmp_path)
    platform = Platform(
        hotbox, RunOptions(transport=broker.url, knowledge="memory", clock="wall",
                           state_dir=tmp_path / "state")
    )
    platform.build()
    results = []
    done = threading.Event()
    admin = open_transport(broker.url)
    admin.connect()

    def answered(message):
        results.append(message.payload)
        if len(results) == 3:
            done.set()

    admin.subscribe("rasm/update/result", answered)
    rules_text = (HOTBOX / "rules" / "hotbox.yaml").read_text()
    inconsistent = rules_text + "  - name: never\n    require: power_limit > 150\n"
    tighter = rules_text.replace("power_limit <= 100", "power_limit <= 90")
    signer = BoundSigner(bytes.fromhex(UPDATE_KEY))
    # the sender learns the process's epoch from its presence message, as an operator's would
    tracker = PresenceTracker(admin).start()

    def push():
        epochs = list(tracker.epochs(app="hotbox").values())
        assert epochs == [platform.assembly.distribution.epoch]
        admin.publish("rasm/update/rules", {"rules": tighter})  # unsigned
        for text in (inconsistent, tighter):
            bound = signer.sign({"rules": text}, topic="rasm/update/rules", epochs=epochs)
            admin.publish("rasm/update/rules", bound)

    platform.on_record.append(
        lambda t, r: (push(), platform.on_record.clear()) if t > 0.5 and tracker.epochs() else None
    )
    stopper = threading.Thread(target=lambda: done.wait(30) and platform.scheduler.stop())
    stopper.start()
    platform.run(30.0)
    stopper.join()
    tracker.stop()
    admin.close()
    broker.stop()
    assert [r["accepted"] for r in results] == [False, False, True], results
    rules = platform.managing.rules[0].rules.rules
    assert "heater_rating" in [r.name for r in rules]
    assert any(r.require_text == "power_limit <= 90" for r in rules)
    lines = (tmp_path / "state" / "timing.lp").read_text().splitlines()
    assert any(line.startswith("maple_stage,stage=monitor") for line in lines)
    json.dumps(results)


def test_a_signing_key_that_is_not_hex_exits_2_with_a_message(tmp_path, monkeypatch, capsys):
    from rasm.cli import main

    monkeypatch.chdir(tmp_path)
    for name in ("RASM_ACTION_KEY", "RASM_UPDATE_KEY"):
        monkeypatch.setenv(name, "not hex")
        assert main(["run", str(HOTBOX), "--clock", "simulated", "--duration", "1"]) == 2
        assert capsys.readouterr().err == (
            f"rasm: {name} must be the signing key in hexadecimal (e.g. `openssl rand -hex 32`)\n"
        )
        monkeypatch.delenv(name)
    # the failed builds released the knowledge file they had opened (the second one above, and
    # any later platform of the process, found it "in use by another storage")
    assert main(["run", str(HOTBOX), "--clock", "simulated", "--duration", "1"]) == 0


def test_the_summary_counts_what_was_refused_from_the_bus(hotbox, tmp_path, monkeypatch):
    import paho.mqtt.client as mqtt

    monkeypatch.setenv("RASM_ACTION_KEY", ACTION_KEY)
    monkeypatch.setenv("RASM_UPDATE_KEY", UPDATE_KEY)
    broker = start_mosquitto(tmp_path)
    garbage = [b"", b"\xff\xfe", b"[1]", b'{"a": NaN}', b'{"mode": "boost", "power_limit": 999}']
    heater, rules = "hotbox/heater", "rasm/update/rules"

    def run(role: str, topic: str):
        platform = Platform(
            hotbox, RunOptions(role=role, transport=broker.url, knowledge="memory",
                               state_dir=tmp_path / role)
        )
        platform.build()
        dist = platform.assembly.distribution

        def refused() -> int:
            return dist.actions_refused + (dist.updates.refused if dist.updates else 0)

        def stop_once_counted() -> None:
            # the gate's own handler for the last message may run after this test's: the run
            # ends once it has counted both refusals (or at its 60 s deadline)
            if refused() >= 2:
                platform.scheduler.stop()
            else:
                platform.scheduler.after(0.01, stop_once_counted)

        # after the garbage, a last valid (and refused) message on the same topic ends the run
        platform.assembly.transport.subscribe(
            topic, lambda m: m.payload.get("last") and platform.scheduler.submit(stop_once_counted),
        )

        def send() -> None:
            client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
            client.connect(broker.host, broker.port)
            client.loop_start()
            for payload in [*garbage, b'{"last": true, "rules": "x", "signature": "00"}']:
                client.publish(topic, payload, qos=1).wait_for_publish(10)
            client.loop_stop()
            client.disconnect()

        platform.scheduler.after(0.2, lambda: threading.Thread(target=send).start())
        return platform.run(60.0)

    try:
        managed = run("managed", heater)
        managing = run("managing", rules)
    finally:
        broker.stop()
    # four are not JSON objects; of the other two, one is unsigned and one wrongly signed
    assert managed.bus == {"malformed messages": 4, "actions refused by the effector gate": 2}
    assert managing.bus == {"malformed messages": 4, "updates refused": 2}


@pytest.mark.slow
def test_an_unreachable_broker_is_one_clear_message_without_traceback(
    tmp_path, monkeypatch, capsys
):
    from rasm.cli import main
    from rasm.testing.servers import free_port

    monkeypatch.chdir(tmp_path)
    url = f"mqtt://127.0.0.1:{free_port()}"  # nothing listens there
    assert main(["run", str(HOTBOX), "--duration", "1", "--transport", url]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err  # the block's failure used to be logged with one
    assert err.splitlines()[-1].startswith(
        f"rasm: building block 'cm' failed to initialise: CommError: could not connect to the "
        f"MQTT broker at {url}"
    )
