"""Instructions per unit of work, counted by valgrind's callgrind: figures that do not drift.

The wall-clock figures of ``benchmarks/statecharts.py`` move by ±20 % within minutes on a shared
machine; instruction counts move by well under 1 %. This script counts them for the cases the
speed work of issue #11 is measured on (docs/performance-statecharts.md), each as the difference
of two runs of different lengths divided by the work between them, so start-up cancels out:

- ``hotbox``: instructions per MAPLE-K iteration of ``run_app(examples/hotbox)`` (101 s minus 1 s
  of simulated time: 200 iterations, 1,000 sensor records);
- ``orchestrator``: per Hotbox-like orchestrator iteration on the platform's interpreter (``tick``,
  ``monitored``, ``no_anomaly`` and the step that finds nothing to do), with and without the
  three ``monitors/`` property statecharts;
- ``flat``: per event of the flat 3-state chart, for stock sismic, rasm and the platform.

With the compiled build (docs/compiled.md) instruction counts understate the gain: the compiled
modules execute about 12 % fewer instructions per Hotbox iteration but take about 30 % less CPU
time (no bytecode dispatch, fewer mispredicted branches). Compare builds in CPU time, and use
these counts to compare changes within one build (``RASM_PURE_PYTHON=1`` for plain Python).

Needs ``valgrind`` on the PATH (``apt-get install -y valgrind``). Run it from the repository:
``.venv/bin/python benchmarks/instructions.py [case ...]``. ``PYTHONHASHSEED`` is fixed to 0.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HOTBOX = """
import sys
from pathlib import Path
from rasm.testing import run_app
run_app(Path({root!r}) / "examples" / "hotbox", seed=1, duration={n} + 1.0)
"""

ORCHESTRATOR = """
import sys
sys.path.insert(0, {bench!r})
import statecharts as s
from pathlib import Path
from sismic.io import import_from_yaml
root = Path({root!r})
chart = import_from_yaml(filepath=str(root / "statecharts" / "adaptation_orchestrator.yaml"))
props = [import_from_yaml(filepath=str(p)) for p in sorted((root / "monitors").glob("*.yaml"))]
_, _, platform, _, _ = s.case(chart, [], props if {monitors} else None)
interp = platform()
interp.execute()
for name in ("configure", "configuration_done", "initialization_done"):
    interp.queue(name)
    interp.execute()
for _ in range({n}):
    interp.clock.time += 0.5
    for name in ("tick", "monitored", "no_anomaly"):
        interp.queue(name)
        interp.execute_once()
    assert interp.execute_once() is None
"""

FLAT = """
import sys
sys.path.insert(0, {bench!r})
import statecharts as s
from sismic.io import import_from_yaml
stock, rasm, platform, events, dt = s.case(import_from_yaml(s.FLAT), ["next"] * {n}, None)
s.run_events({{"stock": stock, "rasm": rasm, "platform": platform}}[{which!r}], events, dt)
"""


def instructions(code: str) -> int:
    """Instructions callgrind counts for ``python -c code``."""
    env = {**os.environ, "PYTHONHASHSEED": "0", "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
         sys.executable, "-c", code],
        env=env, capture_output=True, text=True, check=True,
    )
    found = re.search(r"Collected : (\d+)", done.stderr)
    if found is None:
        raise RuntimeError(f"no instruction count in callgrind's output:\n{done.stderr}")
    return int(found.group(1))


def per_unit(template: str, short: int, long: int, units_per_n: float, **names: object) -> int:
    """Instructions per unit of work: the difference of a long and a short run."""
    counts = [
        instructions(template.format(root=str(ROOT), bench=str(ROOT / "benchmarks"), n=n, **names))
        for n in (short, long)
    ]
    return round((counts[1] - counts[0]) / ((long - short) * units_per_n))


def main(argv: list[str]) -> int:
    if shutil.which("valgrind") is None:
        print("valgrind is not installed: apt-get install -y valgrind", file=sys.stderr)
        return 2
    cases = argv or ["hotbox", "orchestrator", "flat"]
    unknown = set(cases) - {"hotbox", "orchestrator", "flat"}
    if unknown:
        print(f"unknown case(s): {', '.join(sorted(unknown))}", file=sys.stderr)
        return 2
    if "hotbox" in cases:  # seconds of simulated time -> 2 iterations per second
        print(f"hotbox_instructions_per_iteration={per_unit(HOTBOX, 0, 100, 2):,}")
    if "orchestrator" in cases:
        for monitors in (False, True):
            count = per_unit(ORCHESTRATOR, 50, 1050, 1, monitors=monitors)
            print(f"orchestrator_instructions_per_iteration[monitors={monitors}]={count:,}")
    if "flat" in cases:
        for which in ("stock", "rasm", "platform"):
            short, long = (100, 1100) if which == "stock" else (1000, 11000)
            count = per_unit(FLAT, short, long, 1, which=which)
            print(f"flat_instructions_per_event[{which}]={count:,}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
