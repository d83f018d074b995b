"""A robot's trace at 100 Hz and the properties checked on it: the scale tests' input, and
``benchmarks/scale.py``'s."""

from __future__ import annotations

import json
import random
from pathlib import Path

PROPS = """\
input velocity: float
input mode: str = "idle"
event anomaly
event adapted
property velocity_limit:
    always (velocity <= 0.5 or mode == "emergency")
property timely_adaptation:
    always (anomaly -> eventually[0, 2s] adapted)
property smooth:
    always (abs(velocity - prev(velocity)) < 0.45)
property calm:
    always (avg[0, 1s](velocity) < 0.4)
"""


def write_trace(path: Path, records: int, seed: int = 0) -> Path:
    """``records`` records at 100 Hz: velocity on every one, rare anomalies, adaptations and
    mode changes (a mode set once holds across any cut), written 10⁵ lines at a time."""
    rng = random.Random(seed)
    with open(path, "w", encoding="utf-8") as out:
        out.write(json.dumps({"time": 0, "mode": "navigate", "velocity": 0.1}) + "\n")
        lines = []
        for k in range(1, records):
            record: dict = {"time": k / 100, "velocity": round(rng.uniform(0, 0.52), 3)}
            if rng.random() < 0.001:
                record["anomaly"] = True
            if rng.random() < 0.001:
                record["adapted"] = True
            if rng.random() < 0.0002:
                record["mode"] = rng.choice(["navigate", "dock", "emergency"])
            lines.append(json.dumps(record))
            if len(lines) == 100_000:
                out.write("\n".join(lines) + "\n")
                lines = []
        if lines:
            out.write("\n".join(lines) + "\n")
    return path
