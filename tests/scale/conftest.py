"""Fixtures of the scale tests: traces large enough to be cut into parts, and a Dask cluster
(a scheduler and two worker processes under a nanny) on loopback."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rasm.testing.servers import free_port

from .traces import PROPS as BASE_PROPS

ROOT = Path(__file__).resolve().parents[2]
RASM = [sys.executable, "-m", "rasm.cli"]

# the benchmark's properties, and one over the whole past (a cut must carry its memory)
PROPS = BASE_PROPS + """\
property docked_before:
    always (mode == "emergency" -> once (mode == "dock"))
"""


@pytest.fixture
def props(tmp_path: Path) -> Path:
    path = tmp_path / "props.rv"
    path.write_text(PROPS, encoding="utf-8")
    return path


def rasm(*args: str, cwd: Path | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([*RASM, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout)


class DaskCluster:
    """``dask scheduler`` and ``dask worker`` (two processes of one thread, under a nanny) on
    127.0.0.1, stopped at the end."""

    def __init__(self, folder: Path, workers: int = 2) -> None:
        self.port = free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
        self.log = open(folder / "dask.log", "ab")  # noqa: SIM115 - closed in stop()
        self.scheduler = subprocess.Popen(
            [*dask, "--host", "127.0.0.1", "--port", str(self.port), "--no-dashboard"],
            stdout=self.log, stderr=subprocess.STDOUT, cwd=folder)
        self.workers = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", self.address,
             "--nworkers", str(workers), "--nthreads", "1", "--host", "127.0.0.1",
             "--no-dashboard", "--memory-limit", "0", "--local-directory", str(folder)],
            stdout=self.log, stderr=subprocess.STDOUT, cwd=folder)
        from distributed import Client

        deadline = time.monotonic() + 60
        while True:
            try:
                self.client = Client(self.address, timeout=5, set_as_default=False)
                break
            except OSError:
                if time.monotonic() > deadline or self.scheduler.poll() is not None:
                    self.stop()
                    raise RuntimeError((folder / "dask.log").read_text()[-2000:]) from None
                time.sleep(0.1)
        self.client.wait_for_workers(workers, timeout=60)

    def stop(self) -> None:
        if getattr(self, "client", None) is not None:
            self.client.close()
        for process in (self.workers, self.scheduler):
            process.terminate()
        for process in (self.workers, self.scheduler):
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self.log.close()


@pytest.fixture
def dask_cluster(tmp_path: Path):
    pytest.importorskip("distributed")
    cluster = DaskCluster(tmp_path)
    try:
        yield cluster
    finally:
        cluster.stop()


def children(pid: int) -> list[int]:
    """The processes ``pid`` started, and theirs."""
    found = []
    try:
        listed = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return []
    for child in map(int, listed):
        found += [child, *children(child)]
    return found


def cpu_seconds(pid: int) -> float:
    """User and system time a process has used."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
