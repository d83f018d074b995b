"""Fixtures every test folder may use: real mosquitto, redis-server and influxd on free loopback
ports, started here and stopped at teardown, and MQTT transports closed at teardown."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from rasm.comm import MqttTransport
from rasm.testing.servers import (
    Broker,
    InfluxServer,
    RedisServer,
    start_influxdb,
    start_mosquitto,
    start_redis,
)


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


@pytest.fixture(scope="module")
def redis_server(tmp_path_factory) -> Iterator[RedisServer]:
    server = start_redis(tmp_path_factory.mktemp("redis"))
    yield server
    server.stop()


@pytest.fixture(scope="module")
def influx(tmp_path_factory) -> Iterator[InfluxServer]:
    server = start_influxdb(tmp_path_factory.mktemp("influxdb"))
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
def mqtt(broker, mqtt_factory) -> Callable[..., MqttTransport]:
    """``make(**options)``: a connected MqttTransport on the test's broker, closed at teardown."""
    return lambda **options: mqtt_factory(broker.url, **options)
