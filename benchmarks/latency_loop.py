"""Whole-path detect-to-act latency over a loopback mosquitto broker, at 10 and 200 records/s.

    .venv/bin/python benchmarks/latency_loop.py [--seconds 60]

The Hotbox's managed system (simulator) and managing system run as two platforms in this process,
talking only through a real broker. Latency is measured from the managing side's ``anomaly``
record to the moment the managed side applies the resulting action (one wall clock for both), so
it covers Analyse → Plan → Legitimate → Execute → Adaptation Manager → Trustworthiness Manager →
Trustworthiness Checker → the effector's MQTT hop. The records/s rate is the managed system's
sensor rate.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rasm import Platform, RunOptions  # noqa: E402
from rasm.platform.manifest import load_manifest  # noqa: E402
from rasm.testing.servers import start_mosquitto  # noqa: E402

HOTBOX = ROOT / "examples" / "hotbox"


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))]


def measure(rate: float, seconds: float, broker_url: str) -> list[float]:
    scenario = {"openings": [[t, 1.5] for t in range(2, int(seconds), 3)]}
    managed_manifest = load_manifest(HOTBOX)
    managed_manifest.simulator_period = 1.0 / rate
    managing_manifest = load_manifest(HOTBOX)
    managing_manifest.period = 0.1
    managing_manifest.twin = None  # measure the loop, not the twin's learning
    # low_latency as `rasm run` sets it for a live run
    managed = Platform(managed_manifest, RunOptions(
        role="managed",
        transport=broker_url,
        clock="wall",
        scenario=scenario,
        low_latency=True,
    ))
    managing = Platform(managing_manifest, RunOptions(
        role="managing",
        transport=broker_url,
        clock="wall",
        knowledge="memory",
        low_latency=True,
    ))
    managed.build()
    managing.build()
    anomalies: list[float] = []
    latencies: list[float] = []
    apply = managed.assembly.managed_system.simulator.apply

    def applied(effector, payload, t):
        if anomalies:
            latencies.append(time.perf_counter() - anomalies.pop(0))
        return apply(effector, payload, t)

    managed.assembly.managed_system.simulator.apply = applied
    managing.on_record.append(
        lambda t, record: anomalies.append(time.perf_counter()) if record.get("anomaly") else None)
    side = threading.Thread(target=managed.run, args=(seconds + 2,))
    side.start()
    managing.run(seconds)
    side.join()
    return latencies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        broker = start_mosquitto(Path(tmp))
        try:
            print("records/s  adaptations   p50 ms   p90 ms   p99 ms")
            for rate in (10, 200):
                ms = [x * 1000 for x in measure(rate, args.seconds, broker.url)]
                if not ms:
                    print(f"{rate:9d}  no adaptation")
                    continue
                print(f"{rate:9d}  {len(ms):11d}  {percentile(ms, 50):7.2f}  "
                      f"{percentile(ms, 90):7.2f}  {percentile(ms, 99):7.2f}")
        finally:
            broker.stop()


if __name__ == "__main__":
    main()
