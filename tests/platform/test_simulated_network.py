"""A seeded run on the simulated clock gives the same trace over a network transport as on the
in-process bus: the clock moves only once the messages the run published are back. A managed
system in another process cannot be waited for: that combination is refused at start."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rasm import Platform, RunOptions
from rasm.errors import CommError
from rasm.loop import MEASURED_KEYS
from rasm.platform import simulated_clock

from .conftest import read_trace

ROOT = Path(__file__).resolve().parents[2]
RUNS = 3  # the race this guards against lost readings in 2 runs of 3


def seeded_trace(app, tmp_path: Path, name: str, **options) -> list[dict]:
    trace_file = tmp_path / f"{name}.jsonl"
    Platform(app, RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        state_dir=tmp_path / name,
        trace=trace_file,
        **options,
    )).run(20.0)
    return [{k: v for k, v in r.items() if k not in MEASURED_KEYS} for r in read_trace(trace_file)]


@pytest.mark.slow
def test_a_seeded_simulated_run_over_mosquitto_gives_the_in_process_trace(
    hotbox, broker, tmp_path
):
    expected = seeded_trace(hotbox, tmp_path, "local")
    assert any(r.get("executed") for r in expected)  # an action crosses the bus too
    for run in range(RUNS):
        assert seeded_trace(hotbox, tmp_path, f"mqtt-{run}", transport=broker.url) == expected


@pytest.mark.slow
def test_a_simulated_run_whose_reading_never_comes_back_fails_naming_it(
    hotbox, broker, tmp_path, monkeypatch
):
    monkeypatch.setattr(simulated_clock, "DELIVERY_TIMEOUT", 1.0)
    platform = Platform(hotbox, RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        state_dir=tmp_path,
        transport=broker.url,
    ))
    # the broker goes away 5 s into the run: the next readings are lost on the way
    platform.on_record.append(lambda time, record: broker.stop() if time >= 5 else None)
    with pytest.raises(CommError, match=r"did not come back within 1 s \(1 on 'hotbox/sensors'"):
        platform.run(20.0)


def test_a_reading_from_another_process_fails_a_simulated_run(hotbox, broker, mqtt, tmp_path):
    intruder = mqtt()
    platform = Platform(hotbox, RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        state_dir=tmp_path,
        transport=broker.url,
    ))
    sent: list[float] = []

    def intrude(time: float, record: dict) -> None:
        # another process publishes on the probe topic, once: nobody could say when its reading
        # comes (and a record it made would otherwise send another)
        if time >= 5 and "temperature" in record and not sent:
            sent.append(time)
            intruder.publish("hotbox/sensors", {"temperature": 80.0})

    platform.on_record.append(intrude)
    with pytest.raises(CommError, match=r"another process published on topics this process "
                                        r"needs to itself \(1 on 'hotbox/sensors'\)"):
        platform.run(20.0)


def rasm_run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rasm.cli", "run", *args],
                          capture_output=True, text=True, timeout=60, cwd=cwd)


@pytest.mark.parametrize("role", ["managing", "managed"])
def test_a_split_system_on_the_simulated_clock_is_refused_at_start(role, broker, tmp_path):
    run = rasm_run(str(ROOT / "examples" / "hotbox"), "--transport", broker.url, "--role", role,
                   "--clock", "simulated", "--duration", "5", cwd=tmp_path)
    assert run.returncode == 2
    assert f"--clock simulated over {broker.url} needs the managing and the managed system in " \
           "one process" in run.stderr
    assert "--clock wall" in run.stderr and "Traceback" not in run.stderr


def test_an_app_without_a_simulator_on_the_simulated_clock_over_a_network_is_refused(tmp_path):
    # refused before anything connects: no router need listen at the address
    run = rasm_run(str(ROOT / "examples" / "turtlebot" / "ros2.yaml"), "--transport",
                   "zenoh://127.0.0.1:9", "--clock", "simulated", "--duration", "5", cwd=tmp_path)
    assert run.returncode == 2
    assert "needs the app's own simulator (managed_system.simulator in app.yaml)" in run.stderr
    assert "Traceback" not in run.stderr
