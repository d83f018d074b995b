"""Real servers for tests: mosquitto, redis-server and influxd on free loopback ports.

``start_mosquitto(tmp_dir)`` writes a minimal config into ``tmp_dir``, starts ``mosquitto -c`` and
returns once the broker accepts connections (it answers an MQTT CONNECT). Use it from any test
folder, e.g. as a fixture::

    @pytest.fixture
    def broker(tmp_path):
        broker = start_mosquitto(tmp_path)
        yield broker
        broker.stop()
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

__all__ = [
    "Broker",
    "InfluxServer",
    "RedisServer",
    "find_mosquitto",
    "free_port",
    "start_influxdb",
    "start_mosquitto",
    "start_redis",
]

_HOST = "127.0.0.1"  # loopback only: tests never listen on a public interface
_S = TypeVar("_S", bound="_Server")


def find_mosquitto() -> str:
    """Path of the mosquitto binary (it lives in /usr/sbin on Debian/Ubuntu, often not on PATH)."""
    found = shutil.which("mosquitto") or next(
        (p for p in ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto") if os.access(p, os.X_OK)),
        None,
    )
    if found is None:
        raise FileNotFoundError(
            "mosquitto is not installed; install it (apt-get install mosquitto) or run "
            "scripts/test.sh, which does"
        )
    return found


# MQTT 3.1.1 CONNECT (clean session, keepalive 60, client id "rasm-probe") and the CONNACK that
# accepts it: the readiness probe speaks MQTT, so another program on the port does not pass.
_CONNECT = bytes([0x10, 22, 0, 4]) + b"MQTT" + bytes([4, 2, 0, 60, 0, 10]) + b"rasm-probe"
_CONNACK_OK = bytes([0x20, 2, 0, 0])
_DISCONNECT = bytes([0xE0, 0])


def _mqtt_answers(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5) as sock:
            sock.sendall(_CONNECT)
            answer = b""
            while len(answer) < 4:
                chunk = sock.recv(4 - len(answer))
                if not chunk:
                    return False
                answer += chunk
            sock.sendall(_DISCONNECT)
            # any CONNACK means the broker is up, also one refusing an anonymous client (5)
            return answer[:3] == _CONNACK_OK[:3]
    except OSError:
        return False


def free_port() -> int:
    """A TCP port on loopback that nobody was listening on a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((_HOST, 0))
        return sock.getsockname()[1]


# --------------------------------------------------------------------------- the servers


def _find_binary(name: str, package: str) -> str:
    found = shutil.which(name) or next(
        (p for p in (f"/usr/sbin/{name}", f"/usr/bin/{name}") if os.access(p, os.X_OK)), None
    )
    if found is None:
        raise FileNotFoundError(
            f"{name} is not installed; install it (apt-get install {package}) or run "
            "scripts/test.sh, which does"
        )
    return found


def _redis_answers(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5) as sock:
            sock.sendall(b"PING\r\n")
            answer = b""
            while not answer.endswith(b"\r\n"):
                chunk = sock.recv(64)
                if not chunk:
                    return False
                answer += chunk
            return answer == b"+PONG\r\n"
    except OSError:
        return False


def _influx_answers(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5) as sock:
            request = f"GET /ping HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
            sock.sendall(request.encode())
            answer = b""
            while len(answer) < 12:
                chunk = sock.recv(64)
                if not chunk:
                    break
                answer += chunk
            return answer.startswith(b"HTTP/1.1 204")
    except OSError:
        return False


class _Server:
    """A server process with a config file and a log in a temporary folder.

    Subclasses write the config in ``__init__`` and give the command and the readiness probe.
    """

    name = "server"

    def __init__(self, tmp_dir: Path, port: int, timeout: float) -> None:
        self.host = _HOST
        self.port = port
        self.timeout = timeout
        self.dir = Path(tmp_dir)
        self.log = self.dir / f"{self.name}-{port}.log"
        self._process: subprocess.Popen[bytes] | None = None

    def _command(self) -> list[str]:
        raise NotImplementedError

    def _answers(self) -> bool:
        raise NotImplementedError

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def start(self) -> None:
        """Start the server and wait until it answers its protocol; RuntimeError if it cannot."""
        if self.running:
            return
        with open(self.log, "ab") as log:
            self._process = subprocess.Popen(
                self._command(), stdout=log, stderr=subprocess.STDOUT, cwd=self.dir
            )
        deadline = time.monotonic() + self.timeout
        while True:
            if self._answers():
                return
            try:
                # the wait is the pause between probes and notices at once if the server exited
                code = self._process.wait(timeout=0.02)
            except subprocess.TimeoutExpired:
                code = None
            if code is not None or time.monotonic() > deadline:
                self.stop()
                tail = self.log.read_text(errors="replace")[-2000:]
                raise RuntimeError(
                    f"{self.name} did not start on {self.host}:{self.port} "
                    f"(exit code {code}); its log:\n{tail}"
                )

    def stop(self) -> None:
        """Terminate the server (idempotent)."""
        process, self._process = self._process, None
        if process is None or process.poll() is not None:
            return
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)

    def restart(self) -> None:
        """Stop the server and start it again on the same port (Redis: no data survives)."""
        self.stop()
        self.start()

    def __enter__(self) -> _Server:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.url} {'running' if self.running else 'stopped'}>"

    @property
    def url(self) -> str:
        raise NotImplementedError


class Broker(_Server):
    """A mosquitto process: ``host``, ``port``, ``url`` (``mqtt://host:port``), stop, restart."""

    name = "mosquitto"

    def __init__(self, tmp_dir: Path, port: int, timeout: float = 10.0) -> None:
        super().__init__(tmp_dir, port, timeout)
        self.config = self.dir / f"mosquitto-{port}.conf"
        self.config.write_text(
            f"listener {port} {_HOST}\nallow_anonymous true\npersistence false\n"
        )

    @property
    def url(self) -> str:
        """``mqtt://host:port``."""
        return f"mqtt://{self.host}:{self.port}"

    def _command(self) -> list[str]:
        return [find_mosquitto(), "-c", str(self.config)]

    def _answers(self) -> bool:
        return _mqtt_answers(self.host, self.port)


class RedisServer(_Server):
    """A redis-server process without persistence: ``host``, ``port``, ``url``, ``stop``."""

    name = "redis"

    def __init__(self, tmp_dir: Path, port: int, timeout: float = 10.0) -> None:
        super().__init__(tmp_dir, port, timeout)
        self.config = self.dir / f"redis-{port}.conf"
        self.config.write_text(
            f'bind {_HOST}\nport {port}\nsave ""\nappendonly no\ndaemonize no\n'
            f"dir {self.dir}\nlogfile {self.log}\n"
        )

    @property
    def url(self) -> str:
        """``redis://host:port/0``."""
        return f"redis://{self.host}:{self.port}/0"

    def _command(self) -> list[str]:
        return [_find_binary("redis-server", "redis-server"), str(self.config)]

    def _answers(self) -> bool:
        return _redis_answers(self.host, self.port)


class InfluxServer(_Server):
    """An InfluxDB 1.x ``influxd`` with its data in ``tmp_dir``: ``url`` is its HTTP API."""

    name = "influxdb"

    def __init__(self, tmp_dir: Path, port: int, rpc_port: int, timeout: float = 30.0) -> None:
        super().__init__(tmp_dir, port, timeout)
        root = self.dir / f"influxdb-{port}"
        self.config = self.dir / f"influxdb-{port}.conf"
        self.config.write_text(
            "reporting-disabled = true\n"
            f'bind-address = "{_HOST}:{rpc_port}"\n'
            f'[meta]\n  dir = "{root}/meta"\n'
            f'[data]\n  dir = "{root}/data"\n  wal-dir = "{root}/wal"\n'
            "  query-log-enabled = false\n"
            "[monitor]\n  store-enabled = false\n"
            f'[http]\n  bind-address = "{_HOST}:{port}"\n  log-enabled = false\n'
            "[continuous_queries]\n  enabled = false\n"
        )

    @property
    def url(self) -> str:
        """``http://host:port``."""
        return f"http://{self.host}:{self.port}"

    def _command(self) -> list[str]:
        return [_find_binary("influxd", "influxdb"), "run", "-config", str(self.config)]

    def _answers(self) -> bool:
        return _influx_answers(self.host, self.port)


def _start_on_a_free_port(make: Callable[[], _S], attempts: int) -> _S:
    """Start the server ``make()`` makes on ports picked free just before; should another
    process take one in between, try again on new ones (up to ``attempts`` times)."""
    for attempt in range(attempts):
        server = make()
        try:
            server.start()
            return server
        except RuntimeError:
            if attempt == attempts - 1:
                raise
    raise AssertionError("unreachable")


def start_mosquitto(tmp_dir: str | os.PathLike[str], *, attempts: int = 3) -> Broker:
    """Start a mosquitto broker on a free loopback port, with its config and log in
    ``tmp_dir``; returns once it answers an MQTT CONNECT."""
    return _start_on_a_free_port(lambda: Broker(Path(tmp_dir), free_port()), attempts)


def start_redis(tmp_dir: str | os.PathLike[str], *, attempts: int = 3) -> RedisServer:
    """Start a redis-server on a free loopback port, with its config and log in ``tmp_dir``."""
    return _start_on_a_free_port(lambda: RedisServer(Path(tmp_dir), free_port()), attempts)


def start_influxdb(tmp_dir: str | os.PathLike[str], *, attempts: int = 3) -> InfluxServer:
    """Start an InfluxDB 1.x ``influxd`` on free loopback ports (HTTP and RPC), data in
    ``tmp_dir``; returns once ``GET /ping`` answers 204."""
    return _start_on_a_free_port(
        lambda: InfluxServer(Path(tmp_dir), free_port(), free_port()), attempts
    )
