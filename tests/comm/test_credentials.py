"""A broker that wants a user name and password: the transport, `rasm run` and `rasm monitor`."""

from __future__ import annotations

import getpass
import queue
import subprocess
import sys
from pathlib import Path

import pytest

from rasm.comm import MqttTransport
from rasm.comm.url import credentials_from_env
from rasm.errors import CommError
from rasm.testing.servers import Broker, free_port

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def locked_broker(tmp_path):
    """mosquitto on a free loopback port that admits only robot / s3cret."""
    passwords = tmp_path / "passwords"
    subprocess.run(["mosquitto_passwd", "-c", "-b", str(passwords), "robot", "s3cret"], check=True)
    broker = Broker(tmp_path, free_port())
    broker.config.write_text(
        f"listener {broker.port} {broker.host}\nallow_anonymous false\n"
        f"password_file {passwords}\npersistence false\n"
        # run as the tests user (root here), who can read the password file in tmp_path
        f"user {getpass.getuser()}\n"
    )
    broker.start()
    yield broker
    broker.stop()


def test_the_right_credentials_connect_and_carry_messages(locked_broker):
    transport = MqttTransport(locked_broker.url, username="robot", password="s3cret")
    transport.connect()
    try:
        received: queue.Queue = queue.Queue()
        transport.subscribe("t/x", received.put)
        assert transport.wait_connected(5)  # the subscription is confirmed by the broker
        transport.publish("t/x", {"v": 1})
        assert received.get(timeout=5).payload["v"] == 1
    finally:
        transport.close()


@pytest.mark.parametrize("credentials", [{}, {"username": "robot", "password": "wrong"}])
def test_refused_credentials_fail_at_once_saying_where_they_come_from(locked_broker, credentials):
    transport = MqttTransport(locked_broker.url, connect_timeout=30, **credentials)
    with pytest.raises(CommError, match="refused the connection: Not authorized") as error:
        transport.connect()
    # no wait for the 30 s timeout: a refusal is final, and the message says what to set
    assert "RASM_MQTT_USERNAME and RASM_MQTT_PASSWORD" in str(error.value)


def test_credentials_come_from_the_environment_for_mqtt_only():
    env = {"RASM_MQTT_USERNAME": "robot", "RASM_MQTT_PASSWORD": "s3cret"}
    assert credentials_from_env("mqtt://127.0.0.1:1883", env) == {
        "username": "robot",
        "password": "s3cret",
    }
    assert credentials_from_env("local", env) == {}
    assert credentials_from_env("mqtt://127.0.0.1:1883", {}) == {}
    with pytest.raises(CommError, match="RASM_MQTT_USERNAME is not"):
        credentials_from_env("mqtt://h:1", {"RASM_MQTT_PASSWORD": "x"})


@pytest.mark.slow
def test_rasm_run_uses_the_environment_credentials(locked_broker, tmp_path):
    command = [
        sys.executable, "-m", "rasm.cli", "run", str(ROOT / "examples" / "hotbox"),
        "--transport", locked_broker.url, "--role", "managed", "--duration", "1",
    ]
    refused = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert refused.returncode == 2
    assert "refused the connection: Not authorized (no user name" in refused.stderr
    assert "Traceback" not in refused.stderr
    env = {"RASM_MQTT_USERNAME": "robot", "RASM_MQTT_PASSWORD": "s3cret", "PATH": "/usr/bin:/bin"}
    admitted = subprocess.run(
        command, capture_output=True, text=True, cwd=tmp_path, timeout=60, env=env
    )
    assert admitted.returncode == 0, admitted.stderr


def test_a_password_without_a_user_name_is_bad_input(monkeypatch, capsys, tmp_path):
    from rasm.cli import main

    monkeypatch.setenv("RASM_MQTT_PASSWORD", "s3cret")
    monkeypatch.delenv("RASM_MQTT_USERNAME", raising=False)
    monkeypatch.chdir(tmp_path)
    app = str(ROOT / "examples" / "hotbox")
    assert main(["run", app, "--transport", "mqtt://127.0.0.1:1", "--role", "managed"]) == 2
    err = capsys.readouterr().err
    assert "RASM_MQTT_PASSWORD is set but RASM_MQTT_USERNAME is not" in err
    assert "Traceback" not in err
