"""Writes that fail never stop the loop or the fallback: a real full tmpfs under the trace
(JSONL and MCAP), under the knowledge store and the timing file, under a log file, and a
read-only file system. Each failure is logged once with the file and the operation, counted,
the summary says what was lost, and the run exits 1."""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.platform.platform import Platform
from rasm.platform.run_options import RunOptions
from rasm.trace import TraceWriter, format_line
from rasm.trace_mcap import McapTrace, McapTraceWriter

from .conftest import HOTBOX

FALLBACK_APP = HOTBOX / "app.fallback.yaml"
# the seeded fallback run: the band is left at 15.6 s and again at 55.1 s (test_hotbox_fallback)
ENGAGED = [15.6, 55.1]


def _mount(target: Path, options: str) -> None:
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(target)],
                            capture_output=True, text=True)
    if result.returncode:
        pytest.skip(f"cannot mount a tmpfs here ({result.stderr.strip() or 'not root'}): "
                    "the full-disk tests need a real small file system")


@pytest.fixture
def small_disk(tmp_path) -> Iterator[Callable[..., Path]]:
    """``small_disk(kib, read_only=False)``: a fresh tmpfs of that size, unmounted at teardown."""
    mounted: list[Path] = []

    def mount(kib: int, *, read_only: bool = False) -> Path:
        target = tmp_path / f"disk{len(mounted)}"
        target.mkdir()
        _mount(target, f"size={kib}k" + (",ro" if read_only else ""))
        mounted.append(target)
        return target

    yield mount
    for target in mounted:
        subprocess.run(["umount", "-l", str(target)], check=False)


def fill(disk: Path) -> Path:
    """Take every free byte of ``disk`` (a file of its own); returns that file."""
    filler = disk / "filler"
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    try:
        block = b"\0" * 65536
        while True:
            try:
                os.write(fd, block)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC
                if len(block) == 1:
                    break
                block = block[: len(block) // 2]
    finally:
        os.close(fd)
    return filler


def rasm_run(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rasm.cli", "run", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def fell_back_at(stderr: str) -> list[float]:
    """The times the fallback engaged, from the run's log."""
    return [float(line.rsplit("t=", 1)[1]) for line in stderr.splitlines()
            if "fallback engaged" in line]


# ----------------------------------------------------------------------------- the trace


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".jsonl", ".mcap"])
def test_a_full_disk_under_the_trace_stops_neither_the_loop_nor_the_fallback(
        tmp_path, small_disk, suffix):
    disk = small_disk(64)
    trace = disk / f"out{suffix}"
    run = rasm_run(tmp_path, str(FALLBACK_APP), "--clock", "simulated", "--seed", "1",
                   "--duration", "80", "--trace", str(trace))
    assert run.returncode == 1, run.stderr
    reports = [line for line in run.stderr.splitlines() if "rasm.trace" in line]
    assert len(reports) == 1, run.stderr  # once, with the file and the operation
    assert f"trace {trace}: writing failed at t=" in reports[0]
    assert "No space left on device (errno 28)" in reports[0]
    failed_at = float(reports[0].split("failed at t=")[1].split(" s")[0])
    assert "Traceback" not in run.stderr and "a loop job failed" not in run.stderr
    # the fallback engages on the violation that comes while the disk is full, as without it
    assert fell_back_at(run.stderr) == ENGAGED and failed_at < ENGAGED[1]
    assert "fallback engaged 2 times" in run.stdout
    # the summary is printed and says what was lost
    head = next(line for line in run.stdout.splitlines() if "trace records" in line)
    records = int(head.split(" trace records")[0].rsplit(", ", 1)[1])
    (line,) = [line for line in run.stdout.splitlines() if line.startswith(f"  trace {trace}")]
    lost = int(line.rsplit("; ", 1)[1].split(" records lost")[0].replace(",", ""))
    assert "writing failed from t=" in line and "No space left on device" in line
    # the file holds whole records, each one written before the failure
    if suffix == ".jsonl":
        lines = trace.read_text().splitlines()
        kept = [json.loads(text) for text in lines]
    else:
        mcap = McapTrace(trace)
        kept = [json.loads(text) for text in mcap]
        (damage,) = mcap.damage  # a trace cut by a failed write says so when read
        assert "ends without MCAP's summary" in damage.reason
    assert kept and len(kept) + lost == records
    assert kept[-1]["time"] <= failed_at


def test_every_record_reaches_the_checker_and_every_action_its_executed_record(small_disk):
    disk = small_disk(64)
    platform = Platform(FALLBACK_APP, RunOptions(
        clock="simulated",
        seed=1,
        trace=disk / "out.jsonl",
        knowledge="memory",
    ))
    seen: list[dict] = []
    platform.on_record.append(lambda time, record: seen.append({"time": time, **record}))
    summary = platform.run(80)
    failure = summary.write_failures[0]
    assert (failure.what, failure.operation) == ("trace", "writing")
    assert summary.records == len(seen) > failure.lost > 0
    # each action the checker let through has its `executed` record, full disk or not
    trusted = {r["plan"] for r in seen if r.get("trusted")}
    executed = {r["plan"] for r in seen if r.get("executed")}
    assert trusted == executed and {"f1", "f2"} <= executed  # the fallback's actions too
    assert summary.stats.executed == len(executed - {"f1", "f2"})
    assert summary.fallback_engagements == 2 and not summary.ok
    # the checker judged every record, not only those the file kept
    assert summary.outcomes["temperature_band"].judged == len(seen)


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    sizes=st.lists(st.integers(0, 3000), min_size=1, max_size=120),
    free_pages=st.integers(0, 12),
    kind=st.sampled_from([".jsonl", ".mcap"]),
)
def test_a_trace_on_a_full_disk_keeps_whole_records_and_counts_the_rest(
        shared_disk, sizes, free_pages, kind):
    # whatever the records and the free space: the file holds exactly the first k records,
    # whole, and the other n - k are counted as lost; every record reaches the observers
    for leftover in shared_disk.iterdir():
        leftover.unlink()
    page = os.statvfs(shared_disk).f_frsize
    fill(shared_disk)
    with contextlib.suppress(OSError):  # free exactly `free_pages` pages
        os.truncate(shared_disk / "filler",
                    max(0, (shared_disk / "filler").stat().st_size - free_pages * page))
    path = shared_disk / f"trace{kind}"
    try:
        writer = (McapTraceWriter if kind == ".mcap" else TraceWriter)(path)
    except Exception as exc:  # no room for the file's first bytes: refused before the run
        assert "creating the trace" in str(exc) and free_pages == 0
        return
    observed: list[float] = []
    writer.observers.append(lambda time, record: observed.append(time))
    records = [{"s": "x" * n} for n in sizes]
    for k, record in enumerate(records):
        writer.emit(float(k), record)
    writer.close()
    assert observed == [float(k) for k in range(len(records))]
    if kind == ".jsonl":
        kept = path.read_text().splitlines()
        assert kept == [format_line(float(k), r) for k, r in enumerate(records[: len(kept)])]
    else:
        kept = list(McapTrace(path))
        assert kept == [format_line(float(k), r) for k, r in enumerate(records[: len(kept)])]
    lost = writer.failure.lost if writer.failure is not None else 0
    assert len(kept) + lost == len(records)


@pytest.fixture(scope="module")
def shared_disk(tmp_path_factory) -> Iterator[Path]:
    target = tmp_path_factory.mktemp("shared_disk")
    _mount(target, "size=64k")
    yield target
    subprocess.run(["umount", "-l", str(target)], check=False)


# ----------------------------------------------------------------------------- the knowledge store


def test_a_full_disk_under_the_knowledge_store_and_the_timing_file(small_disk, caplog):
    disk = small_disk(2048)
    platform = Platform(FALLBACK_APP, RunOptions(clock="simulated", seed=1,
                                                 state_dir=disk / "state"))
    platform.build()
    filler = fill(disk)

    def free_at_60(time: float, record: dict) -> None:
        if time >= 60 and filler.exists():
            filler.unlink()  # room again: the samples waiting in memory are written

    platform.on_record.append(free_at_60)
    with caplog.at_level(logging.WARNING, logger="rasm"):
        summary = platform.run(80)
    failures = {f.what: f for f in summary.write_failures}
    store = failures["knowledge store"]
    assert store.target == str(disk / "state" / "simulated.sqlite")
    assert store.operation == "committing" and "full" in store.reason
    assert store.failures >= 2 and store.recovered and store.lost == 0
    assert failures["timing file"].lost > 0 and failures["timing file"].recovered
    # each logged once in full, then only counted
    logged = [r.getMessage() for r in caplog.records if "failed at" in r.getMessage()
              or ": writing failed" in r.getMessage()]
    assert len([m for m in logged if "knowledge store" in m]) == 1
    assert len([m for m in logged if "timing file" in m]) == 1
    assert summary.fallback_engagements == 2 and not summary.ok
    # what waited in memory reached the file once there was room
    from rasm.knowledge import open_knowledge

    kb, storage = open_knowledge(f"sqlite:{disk / 'state' / 'simulated.sqlite'}")
    try:
        assert kb.read_sample("temperature").time >= 70
    finally:
        storage.close()


def test_a_full_disk_under_a_log_file_counts_its_lines(tmp_path, small_disk, capfd):
    disk = small_disk(64)
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    manifest = app / "app.fallback.yaml"
    log = disk / "rasm.log"
    manifest.write_text(manifest.read_text()
                        + f"logging:\n  level: info\n  sinks: [console, 'file:{log}']\n")
    platform = Platform(manifest, RunOptions(clock="simulated", seed=1, knowledge="memory"))

    def fill_at_start(time: float, record: dict) -> None:
        if not (disk / "filler").exists():
            fill(disk)  # the log file is open and empty: every line from now on fails

    platform.on_record.append(fill_at_start)
    summary = platform.run(80)
    (failure,) = [f for f in summary.write_failures if f.what == "log file"]
    assert (failure.target, failure.operation, failure.unit) == (str(log), "writing", "lines")
    assert "No space left on device" in failure.reason
    # the four fallback lines at least (engaged, released, twice), each counted
    assert failure.lost >= 4 and summary.fallback_engagements == 2 and not summary.ok
    err = capfd.readouterr().err
    assert "--- Logging error ---" not in err and "Traceback" not in err
    assert err.count(f"log file {log}: writing failed") == 1


# ----------------------------------------------------------------------------- read-only


@pytest.mark.slow
def test_a_read_only_folder_is_refused_at_the_start_naming_the_file_and_the_operation(
        tmp_path, small_disk):
    disk = small_disk(64, read_only=True)
    run = rasm_run(disk, str(HOTBOX), "--clock", "simulated", "--duration", "2")
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert ("rasm: creating the state folder .rasm/hotbox (the knowledge store and the timing "
            "file go there) failed: Read-only file system (errno 30)") in run.stderr
    run = rasm_run(tmp_path, str(HOTBOX), "--clock", "simulated", "--duration", "2",
                   "--trace", str(disk / "out.jsonl"))
    assert run.returncode == 2
    assert (f"rasm: creating the trace {disk / 'out.jsonl'} failed: Read-only file system "
            "(errno 30)") in run.stderr
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    with (app / "app.yaml").open("a") as manifest:
        manifest.write(f"logging:\n  sinks: [console, 'file:{disk / 'rasm.log'}']\n")
    run = rasm_run(tmp_path, str(app), "--clock", "simulated", "--duration", "2")
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert (f"opening the log file {disk / 'rasm.log'} failed: Read-only file system "
            "(errno 30)") in run.stderr
