"""`rasm check PROPS BAG` streams a recording: its peak memory does not grow with the bag."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from rasm.ros2 import TypeStore

ROOT = Path(__file__).resolve().parents[2]
STORE = TypeStore()
T0 = 1_700_000_000_000_000_000

PEAK = textwrap.dedent(
    """
    import resource, sys
    from rasm.cli import main
    code = main(["check", *sys.argv[1:]])
    print(code, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
    """
)


def write_bag(path: Path, count: int) -> Path:
    """``count`` std_msgs/msg/Float64 speeds at 100 Hz, one over the limit early on."""
    codec = STORE.codec("std_msgs/msg/Float64")
    slow, fast = codec.encode({"data": 0.5}), codec.encode({"data": 2.0})
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        speed = writer.add_connection("/speed", "std_msgs/msg/Float64", typestore=STORE.rosbags)
        for k in range(count):
            writer.write(speed, T0 + k * 10_000_000, fast if k == 300 else slow)
    return path


def peak_megabytes(*args: Path | str) -> int:
    out = subprocess.run(
        [sys.executable, "-c", PEAK, *map(str, args)],
        capture_output=True, text=True, check=True, cwd=ROOT,
    ).stdout.split()
    assert out[-2] == "1"  # the violation is found (and explained: the bag is read twice)
    return int(out[-1])


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_the_recording(tmp_path):
    props = tmp_path / "speed.rv"
    props.write_text("input speed: float\nproperty limit: always (speed <= 1.0)\n")
    topics = tmp_path / "topics.yaml"
    topics.write_text(
        "probes:\n  - topic: /speed\n    type: std_msgs/msg/Float64\n"
        "    signals:\n      speed: {field: data, type: float}\n"
    )
    peaks = [
        peak_megabytes(props, write_bag(tmp_path / f"bag{count}", count), "--topics", topics)
        for count in (50_000, 250_000)
    ]
    # five times the messages: the same memory, give or take the allocator; a check that
    # holds the records grows by some 60 MB per 100 000 messages
    assert peaks[1] - peaks[0] < 12, peaks


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_an_mcap_trace(tmp_path):
    from rasm.trace_mcap import McapTraceWriter

    props = tmp_path / "speed.rv"
    props.write_text("input speed: float\nproperty limit: always (speed <= 1.0)\n")
    peaks = []
    for count in (50_000, 250_000):
        trace = McapTraceWriter(tmp_path / f"trace{count}.mcap")
        for k in range(count):
            trace.emit(k / 100, {"speed": 2.0 if k == 300 else 0.5})
        trace.close()
        peaks.append(peak_megabytes(props, trace.path))
    assert peaks[1] - peaks[0] < 12, peaks  # 48 MB both, measured
