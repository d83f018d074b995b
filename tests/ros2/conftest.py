"""Fixtures of the ROS 2 tests: foreign peers in subprocesses (tests/ros2/peer.py, written
without rasm), a loopback-only Cyclone DDS configuration, and transports closed at teardown."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from rasm.testing.servers import free_port

PEER = Path(__file__).with_name("peer.py")
DATA = Path(__file__).with_name("data")
CUSTOM_MSG_DIR = DATA / "rasm_demo" / "msg"

# Cyclone on loopback only: no multicast, the one peer is this machine
CYCLONE_LOOPBACK = (
    '<CycloneDDS><Domain id="any"><General><Interfaces>'
    '<NetworkInterface address="127.0.0.1"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General>"
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers>'
    "<ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>100</MaxAutoParticipantIndex></Discovery>"
    "</Domain></CycloneDDS>"
)


def wait_until(condition: Callable[[], Any], timeout: float = 20.0, what: str = "") -> Any:
    """Poll ``condition`` until it is truthy (returned) or ``timeout`` s pass (AssertionError)."""
    deadline = time.monotonic() + timeout
    pause = threading.Event()
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what or condition}")
        pause.wait(0.01)


class Peer:
    """A running tests/ros2/peer.py: its JSON events as they arrive."""

    def __init__(self, config: dict[str, Any]) -> None:
        env = dict(os.environ, CYCLONEDDS_URI=CYCLONE_LOOPBACK, PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen(
            [sys.executable, str(PEER), json.dumps(config)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=env,
        )
        self.events: list[dict[str, Any]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.events.append(json.loads(line))

    def wait_for(self, condition: Callable[[Peer], Any], timeout: float = 20.0,
                 what: str = "") -> Any:
        def check() -> Any:
            if self.process.poll() is not None and not condition(self):
                raise AssertionError(
                    f"the peer exited ({self.process.returncode}) before {what}: "
                    f"{self.process.stderr.read() if self.process.stderr else ''}"
                )
            return condition(self)

        return wait_until(check, timeout, what)

    def wait_ready(self) -> None:
        self.wait_for(lambda p: any(e["event"] == "ready" for e in p.events), what="ready")

    def messages(self, topic: str | None = None) -> list[dict[str, Any]]:
        return [
            e for e in list(self.events)
            if e["event"] == "message" and (topic is None or e.get("topic") == topic)
        ]

    def stop(self) -> None:
        if self.process.stdin is not None and not self.process.stdin.closed:
            try:
                self.process.stdin.close()
            except BrokenPipeError:
                pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


@pytest.fixture
def peers() -> Iterator[Callable[[dict[str, Any]], Peer]]:
    """``start(config)``: a running peer, stopped at teardown."""
    started: list[Peer] = []

    def start(config: dict[str, Any]) -> Peer:
        peer = Peer(config)
        started.append(peer)
        return peer

    yield start
    for peer in started:
        peer.stop()


@pytest.fixture(scope="session", autouse=True)
def cyclone_on_loopback() -> Iterator[None]:
    """This process's Cyclone DDS domains stay on loopback (read when a domain is created)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CYCLONEDDS_URI", CYCLONE_LOOPBACK)
        yield


@pytest.fixture
def dds_domain() -> int:
    """A domain id of its own per test, so that concurrent runs on this machine never meet."""
    return random.randrange(1, 232)


@pytest.fixture
def zenoh_port() -> int:
    return free_port()


@pytest.fixture
def transports() -> Iterator[Callable[[Any], Any]]:
    """``keep(transport)``: the transport, closed at teardown."""
    made: list[Any] = []

    def keep(transport: Any) -> Any:
        made.append(transport)
        return transport

    yield keep
    for transport in made:
        transport.close()


@pytest.fixture
def zenoh_router(zenoh_port: int) -> Iterator[int]:
    """A Zenoh router configured as rmw_zenoh's ``rmw_zenohd`` is (its default router config:
    gossip on, multicast off, failover brokering between peers), listening on a loopback port
    (yielded); opened with eclipse-zenoh only."""
    import zenoh

    config = zenoh.Config()
    for key, value in {
        "mode": "router",
        "listen/endpoints": [f"tcp/127.0.0.1:{zenoh_port}"],
        "scouting/multicast/enabled": False,
        "scouting/gossip/enabled": True,
        "routing/router/peers_failover_brokering": True,
        "timestamping/enabled": True,
    }.items():
        config.insert_json5(key, json.dumps(value))
    router = zenoh.open(config)
    yield zenoh_port
    router.close()
