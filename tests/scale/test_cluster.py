"""``rasm check --cluster``: the same reports on a Dask distributed cluster (a scheduler and two
workers started on loopback here), the recordings read by the workers where they are, and a
worker killed mid-run replaced, its task done again."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from .conftest import RASM, rasm
from .traces import write_trace


@pytest.fixture
def recordings(tmp_path: Path) -> list[Path]:
    small = [write_trace(tmp_path / f"robot{k}.jsonl", 2_000 + 700 * k, seed=k) for k in range(3)]
    return [*small, write_trace(tmp_path / "large.jsonl", 100_000, seed=9)]


@pytest.mark.parametrize("form", ["json", "text"])
def test_a_cluster_gives_the_reports_of_one_pass(props, recordings, dask_cluster, form):
    here = rasm("check", str(props), *map(str, recordings), "--jobs", "1", "--format", form)
    there = rasm("check", str(props), *map(str, recordings), "--cluster", dask_cluster.address,
                 "--part-size", "300k", "--format", form)
    assert there.returncode == here.returncode == 1, there.stderr
    assert there.stdout == here.stdout and there.stderr == here.stderr == ""


def test_relative_paths_are_read_by_the_workers_where_they_are(props, recordings, dask_cluster):
    folder = recordings[0].parent
    names = [p.name for p in recordings]
    there = rasm("check", props.name, *names, "--cluster", dask_cluster.address,
                 "--format", "json", cwd=folder)
    here = rasm("check", props.name, *[str(p) for p in recordings], "--jobs", "1",
                "--format", "json", cwd=folder)
    assert there.returncode == 1 and there.stdout == here.stdout


def test_a_cluster_worker_killed_mid_run_is_replaced_and_the_report_is_that_of_one_pass(
        props, tmp_path, dask_cluster):
    trace = write_trace(tmp_path / "t.jsonl", 400_000, seed=3)
    here = rasm("check", str(props), str(trace), "--jobs", "1", "--format", "json")
    check = subprocess.Popen([*RASM, "check", str(props), str(trace), "--cluster",
                              dask_cluster.address, "--part-size", "2M", "--format", "json"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = dask_cluster.client
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and time.monotonic() < deadline and check.poll() is None:
        busy = [worker for worker, tasks in client.processing().items() if tasks]
        if busy:
            pids = client.run(os.getpid, workers=busy[:1])
            time.sleep(0.3)  # into its task
            (pid,) = pids.values()
            os.kill(pid, signal.SIGKILL)
            killed = pid
        else:
            time.sleep(0.05)
    out, err = check.communicate(timeout=600)
    assert killed is not None, "no worker was seen at work"
    assert check.returncode == 1, err
    assert out == here.stdout
