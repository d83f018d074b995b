"""The live trace survives the end of a run however it comes (real `rasm run` processes).

SIGKILL loses nothing the loop had written; SIGTERM and SIGINT stop the run in order: knowledge
persisted, trace complete, summary printed, the exit code of a normal end.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rasm.knowledge import open_knowledge
from rasm.testing.servers import start_mosquitto

from .conftest import HOTBOX

# a simulator that says on standard error each reading it is about to publish
WITNESS = '''

class Witness(HotboxSimulator):
    def step(self, time, dt):
        readings = super().step(time, dt)
        import sys

        print(f"witness step {time:.3f}", file=sys.stderr, flush=True)
        return readings
'''

# a property the Hotbox breaks at its first reading
BROKEN = """input temperature: float
property always_freezing:
    always (temperature < 0)
"""


def make_app(tmp_path: Path, *, broken: bool = False) -> Path:
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    with (app / "components.py").open("a") as components:
        components.write(WITNESS)
    text = (app / "app.yaml").read_text()
    text = text.replace("simulator: components:HotboxSimulator", "simulator: components:Witness")
    if broken:
        (app / "properties" / "broken.rv").write_text(BROKEN)
        text = text.replace(
            "  - properties/hotbox.rv\n", "  - properties/hotbox.rv\n  - properties/broken.rv\n"
        )
    (app / "app.yaml").write_text(text)
    return app


def start_run(cwd: Path, app: Path, *args: str) -> subprocess.Popen:
    """``rasm run APP ARGS``: standard output to ``cwd/out.txt``, standard error a pipe."""
    return subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(app), *args],
        cwd=cwd,
        stdout=(cwd / "out.txt").open("w"),
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def watch_steps(child: subprocess.Popen, count: int, *, deadline: float = 60.0) -> list[float]:
    """Read the witness's lines from the child's standard error until it announced ``count``
    readings (the child is killed if that takes longer than ``deadline`` seconds)."""
    guard = threading.Timer(deadline, child.kill)
    guard.start()
    steps: list[float] = []
    other: list[str] = []
    try:
        for line in child.stderr:  # blocks on the pipe: no polling
            if line.startswith("witness step "):
                steps.append(float(line.split()[-1]))
                if len(steps) >= count:
                    break
            else:
                other.append(line)
    finally:
        guard.cancel()
    assert len(steps) >= count, "the run never got that far:\n" + "".join(other)
    return steps


def read_lines(path: Path) -> list[dict]:
    """Every line of a trace file, each of which must be whole JSON."""
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    assert text.endswith("\n") or not text, "the last line was cut"
    return [json.loads(line) for line in text.splitlines()]


@pytest.mark.slow
def test_sigkill_loses_no_record_the_loop_had_written(tmp_path):
    app = make_app(tmp_path)
    child = start_run(tmp_path, app, "--duration", "120", "--trace", "out.jsonl")
    try:
        steps = watch_steps(child, 25)
        child.send_signal(signal.SIGKILL)
    finally:
        child.wait(30)
    assert child.returncode == -signal.SIGKILL
    readings = [r for r in read_lines(tmp_path / "out.jsonl") if "temperature" in r]
    # every reading published before the last one announced had been digested by the loop
    # (its job runs before the next simulator step) and written: all of them are on disk
    assert len(readings) >= len(steps) - 1
    assert readings[-1]["time"] >= steps[-2] - 1e-6


@pytest.mark.slow
def test_sigkill_leaves_an_mcap_trace_that_rasm_reads_and_checks(tmp_path, capsys):
    from rasm.cli import main
    from rasm.trace_mcap import McapTrace

    app = make_app(tmp_path)
    child = start_run(tmp_path, app, "--duration", "120", "--trace", "out.mcap")
    try:
        steps = watch_steps(child, 25)
        child.send_signal(signal.SIGKILL)
    finally:
        child.wait(30)
    trace = tmp_path / "out.mcap"
    # killed in its first 64 kB, as the chunked writer lost everything: every record is there
    assert trace.stat().st_size < 64 * 1024
    read = McapTrace(trace)
    readings = [r for r in map(json.loads, read) if "temperature" in r]
    assert len(readings) >= len(steps) - 1
    assert readings[-1]["time"] >= steps[-2] - 1e-6
    (damage,) = read.damage  # the summary the killed writer never wrote
    assert damage.where == "the end of the file" and "ends without" in damage.reason
    # `rasm check` reads it as the rasm trace it is, checks what it holds, reports the damage
    props = tmp_path / "props.rv"
    props.write_text("input temperature: float\nproperty warm: always (temperature > -40)\n")
    assert main(["check", str(props), str(trace), "--format", "json"]) == 1
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["records"] >= len(readings)
    assert report["properties"][0]["verdict"] == "inconclusive"
    assert "the end of the file" in captured.err and "rosbag2" not in captured.err
    assert main(["check", str(props), str(trace), "--allow-damaged"]) == 0


def persisted_temperature(cwd: Path) -> tuple[float, float]:
    """The latest temperature in the SQLite knowledge of a wall-clock Hotbox run in ``cwd``."""
    kb, storage = open_knowledge(f"sqlite:{cwd / '.rasm' / 'hotbox' / 'knowledge.sqlite'}")
    try:
        sample = kb.read_sample("temperature")
        return sample.time, sample.value
    finally:
        storage.close()


def summary_records(out: str) -> int:
    found = re.search(r"(\d+)\s+trace\s+records", out)
    assert found, out
    return int(found.group(1))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "broken", "code"),
    [(signal.SIGTERM, False, 0), (signal.SIGINT, True, 1)],
    ids=["sigterm-satisfied", "sigint-violated"],
)
def test_a_signal_stops_a_live_run_in_order(tmp_path, sig, broken, code):
    app = make_app(tmp_path, broken=broken)
    child = start_run(tmp_path, app, "--duration", "120", "--trace", "out.jsonl")
    try:
        watch_steps(child, 20)
        child.send_signal(sig)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
    out = (tmp_path / "out.txt").read_text()
    # the exit code of a normal end: 0 when every property holds, 1 when one is violated
    assert child.returncode == code, out + err
    assert f"stopped by {signal.Signals(sig).name}" in out
    assert ("always_freezing" in out and "violated" in out) == broken
    assert "Traceback" not in err
    # the trace is complete: every line whole, as many as the summary counted
    records = read_lines(tmp_path / "out.jsonl")
    assert len(records) == summary_records(out) > 20
    # the knowledge was persisted up to the last reading the loop stored
    last = [r for r in records if "temperature" in r][-1]
    stored_time, stored_value = persisted_temperature(tmp_path)
    assert stored_value == last["temperature"]
    assert abs(stored_time - last["time"]) < 1e-6


def test_sigterm_stops_a_simulated_run_in_order(tmp_path):
    app = make_app(tmp_path)
    child = start_run(
        tmp_path, app, "--clock", "simulated", "--duration", "1e9", "--trace", "out.jsonl"
    )
    try:
        watch_steps(child, 200)
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
    out = (tmp_path / "out.txt").read_text()
    assert child.returncode == 0, out + err
    assert "stopped by SIGTERM" in out
    records = read_lines(tmp_path / "out.jsonl")
    assert len(records) == summary_records(out)
    # the summary's duration is the simulated time actually run, not the 1e9 s asked for
    ran = float(re.search(r"([\d.e+]+) s on the simulated clock", out).group(1))
    assert records[-1]["time"] - 1.0 <= ran < 1e9


@pytest.mark.slow
def test_sigterm_stops_both_roles_over_a_broker_in_order(tmp_path):
    broker = start_mosquitto(tmp_path)
    managed_dir, managing_dir = tmp_path / "managed", tmp_path / "managing"
    managed_dir.mkdir()
    managing_dir.mkdir()
    app = make_app(tmp_path)
    common = ("--transport", broker.url, "--duration", "120")
    managed = start_run(managed_dir, app, "--role", "managed", *common)
    managing = start_run(
        managing_dir, app, "--role", "managing", *common, "--trace", "out.jsonl"
    )
    try:
        watch_steps(managed, 10)
        trace = managing_dir / "out.jsonl"
        deadline = time.monotonic() + 60
        # a reading crossed the broker and the loop ran an iteration: every property is judged,
        # so the stop's exit code is that of a normal end (a run stopped before its first
        # iteration has properties never judged, which fails)
        while not (
            any("temperature" in r for r in read_lines(trace))
            and any("stage" in r for r in read_lines(trace))
        ):
            assert time.monotonic() < deadline, "no reading crossed the broker, or no iteration"
            assert managing.poll() is None, managing.stderr.read()
            time.sleep(0.05)
        for child in (managing, managed):
            child.send_signal(signal.SIGTERM)
        errors = [child.communicate(timeout=60)[1] for child in (managing, managed)]
    finally:
        for child in (managing, managed):
            if child.poll() is None:
                child.kill()
        broker.stop()
    ends = zip((managing, managed), (managing_dir, managed_dir), errors, strict=True)
    for child, where, err in ends:
        out = (where / "out.txt").read_text()
        assert child.returncode == 0, out + err
        assert "stopped by SIGTERM" in out
    records = read_lines(managing_dir / "out.jsonl")
    assert len(records) == summary_records((managing_dir / "out.txt").read_text())


def test_a_second_signal_during_the_stop_aborts_at_once(hotbox):
    from rasm import Platform, RunOptions
    from rasm.cli.live import _stop_on_signals

    platform = Platform(hotbox, RunOptions(clock="simulated", knowledge="memory"))
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt), _stop_on_signals(platform):
        signal.raise_signal(signal.SIGTERM)
        assert platform.stopped_by == "SIGTERM"  # the first asks for an orderly stop ...
        signal.raise_signal(signal.SIGINT)  # ... a second aborts
        pytest.fail("the second signal did not abort")
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--trace", "t.jsonl", "--trace-rotate", "0"], "a size must be positive"),
        (["--trace", "t.jsonl", "--trace-rotate", "64X"], "is not a size"),
        (["--trace", "t.jsonl", "--trace-rotate", "nan"], "is not a size"),
        (["--trace", "t.jsonl", "--trace-rotate", "1M", "--trace-keep", "-1"], "0 or more"),
        (["--trace-rotate", "1M"], "--trace-rotate needs --trace FILE"),
        (["--trace", "-", "--trace-rotate", "1M"], "--trace-rotate needs --trace FILE"),
    ],
)
def test_a_bad_rotation_is_bad_usage(tmp_path, args, message):
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--clock", "simulated", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr
    assert not list(tmp_path.glob("t*.jsonl"))


def test_rasm_run_rotates_its_trace_by_size(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--clock", "simulated",
         "--duration", "60", "--trace", "t.jsonl", "--trace-rotate", "10k", "--trace-keep", "3"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    files = [tmp_path / name for name in ("t.3.jsonl", "t.2.jsonl", "t.1.jsonl", "t.jsonl")]
    assert sorted(tmp_path.glob("t*.jsonl")) == sorted(files)
    records = [record for file in files for record in read_lines(file)]
    assert all(file.stat().st_size <= 10_000 for file in files)
    times = [r["time"] for r in records]
    assert times == sorted(times) and times[-1] == pytest.approx(60, abs=0.5)
