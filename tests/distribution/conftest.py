"""Fixtures of the distribution tests: real mosquitto, redis-server and influxd on free loopback
ports, started here and stopped at teardown; transports closed at teardown."""

from __future__ import annotations

import queue
from collections.abc import Callable, Iterator

import pytest

from rasm.comm import Message, MqttTransport
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
    server = start_mosquitto(tmp_path)
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
def mqtt(broker) -> Iterator[Callable[..., MqttTransport]]:
    """``make(**options)``: a connected MqttTransport on the test's broker, closed at teardown."""
    made: list[MqttTransport] = []

    def make(**options) -> MqttTransport:
        transport = MqttTransport(broker.url, **options)
        made.append(transport)
        transport.connect()
        return transport

    yield make
    for transport in made:
        transport.close()


class Inbox:
    """Messages of one subscription, awaited with a timeout (no sleeps)."""

    def __init__(self) -> None:
        self.queue: queue.Queue[Message] = queue.Queue()

    def __call__(self, message: Message) -> None:
        self.queue.put(message)

    def get(self, timeout: float = 10.0) -> Message:
        return self.queue.get(timeout=timeout)

    def take(self, n: int, timeout: float = 10.0) -> list[Message]:
        return [self.get(timeout) for _ in range(n)]

    def empty(self) -> bool:
        return self.queue.empty()
