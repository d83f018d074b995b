"""rasm.testing.servers.start_mosquitto: a real broker on a free loopback port."""

from __future__ import annotations

import socket

import pytest

from rasm.testing.servers import Broker, start_mosquitto


def _accepts(broker: Broker) -> bool:
    try:
        with socket.create_connection((broker.host, broker.port), timeout=2):
            return True
    except OSError:
        return False


def test_start_stop_restart(tmp_path):
    broker = start_mosquitto(tmp_path)
    try:
        assert broker.host == "127.0.0.1"
        assert broker.url == f"mqtt://127.0.0.1:{broker.port}"
        assert broker.running and _accepts(broker)
        assert "listener" in broker.config.read_text()
        broker.stop()
        broker.stop()  # idempotent
        assert not broker.running and not _accepts(broker)
        port = broker.port
        broker.restart()
        assert broker.port == port and broker.running and _accepts(broker)
    finally:
        broker.stop()


def test_two_brokers_get_different_ports(tmp_path):
    with start_mosquitto(tmp_path) as one, start_mosquitto(tmp_path) as two:
        assert one.port != two.port
        assert _accepts(one) and _accepts(two)


def test_a_broker_that_cannot_start_says_why(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        broker = Broker(tmp_path, taken.getsockname()[1], timeout=5)
        with pytest.raises(RuntimeError, match="did not start"):
            broker.start()
        assert not broker.running
