"""Whole-loop figures for the Hotbox: simulated speed, live detect-to-act latency, idle CPU.

    .venv/bin/python benchmarks/loop.py [--quick]

1. Loop iterations per second on the simulated clock (CPU time of this process, so other load
   on the machine does not count).
2. Detect-to-act latency (``anomaly`` record -> ``executed`` record of the same iteration) on
   the wall clock, in process, over many lid openings: p50/p90/p99.
3. CPU share of an idle wall-clock run (no disturbance: the loop ticks at 2 Hz and the simulator
   at 10 Hz, nothing adapts). The public prototype's idle loop burns 65-80 % of a core.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rasm import Platform, RunOptions  # noqa: E402
from rasm.platform.manifest import load_manifest  # noqa: E402

HOTBOX = ROOT / "examples" / "hotbox"


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    k = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[k]


def simulated_speed(seconds: float) -> tuple[int, float]:
    platform = Platform(load_manifest(HOTBOX), RunOptions(clock="simulated", seed=1,
                                                          knowledge="memory"))
    platform.build()
    start = time.process_time()
    summary = platform.run(seconds)
    cpu = time.process_time() - start
    return summary.stats.iterations, summary.stats.iterations / cpu


def live_latency(seconds: float) -> list[float]:
    manifest = load_manifest(HOTBOX)
    manifest.period = 0.1
    openings = [[t, 1.5] for t in range(1, int(seconds), 3)]
    with tempfile.TemporaryDirectory() as tmp:
        trace = Path(tmp) / "trace.jsonl"
        Platform(manifest, RunOptions(
            clock="wall",
            seed=1,
            knowledge="memory",
            trace=trace,
            scenario={"openings": openings},
        )).run(seconds)
        records = [json.loads(line) for line in trace.read_text().splitlines()]
    latencies, anomaly_at = [], None
    for record in records:
        if record.get("anomaly"):
            anomaly_at = record["time"]
        elif record.get("executed") and anomaly_at is not None:
            latencies.append(record["time"] - anomaly_at)
            anomaly_at = None
    return latencies


def idle_cpu(seconds: float) -> float:
    platform = Platform(load_manifest(HOTBOX), RunOptions(
        clock="wall",
        seed=1,
        knowledge="memory",
        scenario={"first_lid_opening": 1e9},
    ))
    platform.build()
    wall, cpu = time.monotonic(), time.process_time()
    platform.run(seconds)
    return (time.process_time() - cpu) / (time.monotonic() - wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    args = parser.parse_args()
    scale = 0.25 if args.quick else 1.0
    iterations, rate = simulated_speed(400 * scale)
    print(f"simulated Hotbox: {iterations} iterations, {rate:,.0f} iterations/s (CPU time)")
    latencies = live_latency(30 * scale)
    if latencies:
        ms = [x * 1000 for x in latencies]
        print(f"live detect-to-act over {len(ms)} adaptations: p50 {percentile(ms, 50):.3f} ms, "
              f"p90 {percentile(ms, 90):.3f} ms, p99 {percentile(ms, 99):.3f} ms")
    else:
        print("live detect-to-act: no adaptation happened")
    share = idle_cpu(10 * scale)
    print(f"idle wall-clock run: {share * 100:.2f} % of a core (target < 2 %)")


if __name__ == "__main__":
    main()
