"""Fixtures of the comm tests: real mosquitto brokers on free loopback ports, and transports
that are closed at teardown."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from rasm.comm import LocalTransport, MqttTransport
from rasm.testing.servers import Broker, start_mosquitto


@pytest.fixture
def broker(tmp_path) -> Iterator[Broker]:
    """A fresh broker for one test (tests that stop and restart it use this one)."""
    server = start_mosquitto(tmp_path)
    yield server
    server.stop()


@pytest.fixture(scope="module")
def shared_broker(tmp_path_factory) -> Iterator[Broker]:
    """One broker for a whole module (hypothesis tests run many examples against it)."""
    server = start_mosquitto(tmp_path_factory.mktemp("mosquitto"))
    yield server
    server.stop()


@pytest.fixture
def mqtt_factory() -> Iterator[Callable[..., MqttTransport]]:
    """``make(url, **options)``: a connected MqttTransport, closed at teardown."""
    made: list[MqttTransport] = []

    def make(url: str, *, connect: bool = True, **options) -> MqttTransport:
        transport = MqttTransport(url, **options)
        made.append(transport)
        if connect:
            transport.connect()
        return transport

    yield make
    for transport in made:
        transport.close()


@pytest.fixture
def local() -> Iterator[LocalTransport]:
    transport = LocalTransport()
    transport.connect()
    yield transport
    transport.close()
