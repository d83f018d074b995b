"""The paths users wait on, each beside its peer or floor in one run.

    .venv/bin/python benchmarks/user_paths.py [--quick]

1. **A simulated hour with the embedded defaults**: ``rasm run examples/hotbox --clock simulated
   --duration 3600`` (SQLite knowledge, timing lines to a file) against the same run with
   ``knowledge: memory`` and ``timing: off`` — what the defaults cost on top of the loop.
   Goal: ratio <= 1.3.
2. **``rasm check`` on a large file**: a 1e6-record JSONL trace (``always (b -> once[0, 1s] a)``)
   against reelay fed record by record from ``json.loads`` of the same file; CPU seconds and
   peak memory of each, in its own process. Goal: rasm >= 1.5x reelay's speed, peak <= 64 MB.
3. **Start-up**: ``rasm --help``, ``rasm lint`` and ``rasm check`` on tiny inputs (wall seconds),
   and what the pytest plugin adds to every pytest start (``import rasm.testing.plugin``).
   Goal: each command <= 0.15 s; the plugin ~0.

Every figure is the median of 3 runs (5 for start-up); the ratios are printed last.
"""

from __future__ import annotations

import argparse
import json
import random
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HOTBOX = ROOT / "examples" / "hotbox"
RASM = [sys.executable, "-m", "rasm.cli"]
PROPERTY = "input a: bool\ninput b: bool\nproperty p: always (b -> once[0, 1s] a)\n"


def timed(command: list[str], cwd: Path) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the child) of one run of ``command``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, cwd=cwd, check=False, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def peak(code: str, *args: str) -> tuple[float, float]:
    """(CPU seconds, peak MB) of ``code`` run in a fresh interpreter (it prints its CPU time)."""
    script = code + (
        "\nimport resource, sys\n"
        "u = resource.getrusage(resource.RUSAGE_SELF)\n"
        "print(u.ru_utime + u.ru_stime, u.ru_maxrss / 1024)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script, *args], capture_output=True, text=True, check=True
    ).stdout.split()
    return float(out[-2]), float(out[-1])


def simulated_hour(repeats: int, duration: float) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        lean = work / "lean"
        shutil.copytree(HOTBOX, lean, ignore=shutil.ignore_patterns("__pycache__"))
        manifest = (lean / "app.yaml").read_text()
        manifest = manifest.replace("knowledge: sqlite", "knowledge: memory")
        (lean / "app.yaml").write_text(manifest + "timing: off\n")
        runs: dict[str, list[float]] = {"defaults": [], "memory, no timing": []}
        for _ in range(repeats):
            for name, app in (("defaults", HOTBOX), ("memory, no timing", lean)):
                command = [*RASM, "run", str(app), "--clock", "simulated", "--seed", "1",
                           "--duration", str(duration)]
                runs[name].append(timed(command, work)[1])
        medians = {name: statistics.median(cpu) for name, cpu in runs.items()}
        for name, cpu in medians.items():
            print(f"simulated {duration:g} s, {name}: {cpu:.2f} s CPU")
        return medians["defaults"] / medians["memory, no timing"]


def large_check(repeats: int, records: int) -> tuple[float, float]:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        props, trace = work / "p.rv", work / "t.jsonl"
        props.write_text(PROPERTY)
        rng = random.Random(1)
        with trace.open("w") as out:
            for k in range(records):
                record = {"time": round(k * 0.01, 2), "a": rng.random() < 0.3,
                          "b": rng.random() < 0.1}
                out.write(json.dumps(record) + "\n")
        size = trace.stat().st_size / 1e6
        rasm_code = (
            "import sys\nfrom rasm.cli import main\n"
            "main(['check', sys.argv[1], sys.argv[2], '--format', 'json'])"
        )
        # reelay's discrete-time monitor counts records: at 100 Hz, 1 s is 100 records
        reelay_code = (
            "import json, sys, reelay\n"
            "m = reelay.discrete_timed_monitor("
            "pattern='historically({b} -> once[0:100]{a})', condense=False)\n"
            "for line in open(sys.argv[1]):\n"
            "    r = json.loads(line); del r['time']; m.update(r)\n"
        )
        rasm_runs = [peak(rasm_code, str(props), str(trace)) for _ in range(repeats)]
        reelay_runs = [peak(reelay_code, str(trace)) for _ in range(repeats)]
        rasm_cpu = statistics.median(r[0] for r in rasm_runs)
        rasm_mb = max(r[1] for r in rasm_runs)
        reelay_cpu = statistics.median(r[0] for r in reelay_runs)
        reelay_mb = max(r[1] for r in reelay_runs)
        print(f"rasm check, {records:,} records ({size:.0f} MB): {rasm_cpu:.2f} s CPU, "
              f"{rasm_mb:.0f} MB peak")
        print(f"reelay from json.loads, same file: {reelay_cpu:.2f} s CPU, {reelay_mb:.0f} MB peak")
        return reelay_cpu / rasm_cpu, rasm_mb


def start_up(repeats: int) -> tuple[float, float]:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "p.rv").write_text(PROPERTY)
        (work / "t.jsonl").write_text('{"time": 0, "a": true, "b": false}\n')
        commands = {
            "rasm --help": [*RASM, "--help"],
            "rasm lint p.rv": [*RASM, "lint", "p.rv"],
            "rasm check p.rv t.jsonl": [*RASM, "check", "p.rv", "t.jsonl"],
        }
        slowest = 0.0
        for name, command in commands.items():
            wall = statistics.median(timed(command, work)[0] for _ in range(repeats))
            slowest = max(slowest, wall)
            print(f"{name}: {wall:.3f} s")
        bare = statistics.median(
            timed([sys.executable, "-c", "pass"], work)[0] for _ in range(repeats)
        )
        plugin = statistics.median(
            timed([sys.executable, "-c", "import rasm.testing.plugin"], work)[0]
            for _ in range(repeats)
        )
        print(f"python -c pass: {bare:.3f} s; import rasm.testing.plugin: {plugin:.3f} s")
        return slowest, plugin - bare


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, one repetition")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    hour = simulated_hour(repeats, 600 if args.quick else 3600)
    speed, megabytes = large_check(repeats, 200_000 if args.quick else 1_000_000)
    slowest, plugin = start_up(1 if args.quick else 5)
    print(f"defaults_over_memory={hour:.2f}")
    print(f"check_over_reelay={speed:.2f}")
    print(f"check_peak_mb={megabytes:.0f}")
    print(f"slowest_command_s={slowest:.3f}")
    print(f"plugin_import_s={plugin:.3f}")


if __name__ == "__main__":
    main()
