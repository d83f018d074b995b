"""Fixtures of the comm tests (the brokers and MQTT transports are in tests/conftest.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from rasm.comm import LocalTransport


@pytest.fixture
def local() -> Iterator[LocalTransport]:
    transport = LocalTransport()
    transport.connect()
    yield transport
    transport.close()
