"""Fixtures every test folder may use: real mosquitto, redis-server and influxd on free loopback
ports, started here and stopped at teardown, MQTT transports closed at teardown, and the
session's wheelhouse for packagings."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path

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


@pytest.fixture(scope="session")
def wheelhouse(request: pytest.FixtureRequest, tmp_path_factory) -> Iterator[Path]:
    """The wheelhouse (``RASM_WHEELHOUSE``) every packaging of the session uses, in this process
    and in the commands the guides run: rasm's wheel is built once per state of its source and
    the dependencies are downloaded once. It is kept in pytest's cache (``.pytest_cache``), so a
    later session finds both; a ``RASM_WHEELHOUSE`` already set is used as it is."""
    configured = os.environ.get("RASM_WHEELHOUSE")
    if configured:
        yield Path(configured)
        return
    cache = getattr(request.config, "cache", None)  # absent under -p no:cacheprovider
    house = cache.mkdir("rasm-wheelhouse") if cache else tmp_path_factory.mktemp("wheelhouse")
    with pytest.MonkeyPatch.context() as env:
        env.setenv("RASM_WHEELHOUSE", str(house))
        yield house


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
