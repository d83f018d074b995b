"""The paths users wait on, each beside its peer or floor in one run.

    .venv/bin/python benchmarks/user_paths.py [--quick] [--only hour|check|start-up]

1. **A simulated hour with the embedded defaults**: ``rasm run examples/hotbox --clock simulated
   --duration 3600`` (SQLite knowledge, timing lines to a file) against the same run with
   ``knowledge: memory`` and ``timing: off`` — what the defaults cost on top of the loop.
   Goal: ratio <= 1.3.
2. **``rasm check`` on a large file**: a 1e6-record JSONL trace (``always (b -> once[0, 1s] a)``)
   against reelay fed record by record from ``json.loads`` of the same file; CPU seconds and
   peak memory of each, in its own process (``--jobs 1``: one process, as reelay's; checking
   in parts side by side is ``benchmarks/scale.py``'s). Goal: rasm >= 1.5x reelay's speed, peak
   <= 64 MB.
3. **``rasm check`` explaining a violation at the end**: the same kind of trace with ``b`` left
   without ``a`` in its last seconds, checked with the text report, which explains the violations
   from the trace read again; against the same trace when it holds. Goal: the same peak memory
   (<= 64 MB).
4. **Start-up**: ``rasm --help``, ``rasm lint`` and ``rasm check`` on tiny inputs (wall seconds),
   and what the pytest plugin adds to every pytest start (``import pytest, rasm.testing.plugin``
   against ``import pytest``). As a user runs them: Python's bytecode cache and rasm's parser
   cache written by a first run (the run without the parser cache is printed too).
   Beside them, a bare interpreter (``python -c pass``), the floor.
   Goal: each command <= 0.15 s, ``rasm check`` <= 10x the bare interpreter; the plugin ~0.

Every figure is the median of 3 runs (9 for start-up, interleaved); the ratios are printed
last.
"""

from __future__ import annotations

import argparse
import json
import os
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


def run(command: list[str], **options) -> str:
    """The output of ``command``; a command that fails stops the benchmark with its output, so
    that no figure comes from a run that did not do its work."""
    done = subprocess.run(command, capture_output=True, text=True, **options)
    if done.returncode != 0:
        output = done.stdout + done.stderr
        sys.exit(f"{' '.join(command)} failed (exit {done.returncode}):\n{output}")
    return done.stdout


def timed(command: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the child) of one run of ``command``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run(command, cwd=cwd, env=env)
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
    out = run([sys.executable, "-c", script, *args]).split()
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
            "argv = ['check', sys.argv[1], sys.argv[2], '--format', 'json', '--jobs', '1']\n"
            "if main(argv) != 0:\n"
            "    sys.exit('rasm check did not find the property satisfied')"
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


def late_violation(repeats: int, records: int) -> tuple[float, float]:
    """(peak MB, CPU ratio) of the text report of a trace violated in its last second, against
    the same trace holding."""
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        props = work / "p.rv"
        props.write_text(PROPERTY)
        traces = {}
        for name in ("holds", "violated at the end"):
            trace = traces[name] = work / f"{name.split()[0]}.jsonl"
            with trace.open("w") as out:
                for k in range(records):
                    late = name != "holds" and k >= records - 200  # no a in the last 2 s
                    record = {"time": round(k * 0.01, 2), "a": not late and k % 7 == 0,
                              "b": k % 11 == 0}
                    out.write(json.dumps(record) + "\n")
        code = (
            "import sys\nfrom rasm.cli import main\n"
            "if main(['check', sys.argv[1], sys.argv[2], '--jobs', '1']) != int(sys.argv[3]):\n"
            "    sys.exit('rasm check did not give the verdict the trace was made for')"
        )
        found = {}
        for name, trace in traces.items():
            exit_code = "0" if name == "holds" else "1"
            runs = [peak(code, str(props), str(trace), exit_code) for _ in range(repeats)]
            found[name] = (statistics.median(r[0] for r in runs), max(r[1] for r in runs))
            print(f"rasm check (text), {records:,} records, {name}: {found[name][0]:.2f} s CPU, "
                  f"{found[name][1]:.0f} MB peak")
        late, holds = found["violated at the end"], found["holds"]
        return late[1], late[0] / holds[0]


def start_up(repeats: int) -> tuple[float, float, float]:
    # as installed: bytecode cached (this environment may forbid writing it), parser cached
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "p.rv").write_text(PROPERTY)
        (work / "t.jsonl").write_text('{"time": 0, "a": true, "b": false}\n')
        commands = {
            "python -c pass": [sys.executable, "-c", "pass"],  # the floor: a bare interpreter
            "rasm --help": [*RASM, "--help"],
            "rasm lint p.rv": [*RASM, "lint", "p.rv"],
            "rasm check p.rv t.jsonl": [*RASM, "check", "p.rv", "t.jsonl"],
        }
        for command in commands.values():
            timed(command, work, env)  # writes the caches
        runs: dict[str, list] = {name: [] for name in commands}
        for _ in range(repeats):  # interleaved: a load spike hits every command alike
            for name, command in commands.items():
                runs[name].append(timed(command, work, env))
        walls = {}
        for name in commands:
            walls[name] = statistics.median(run[0] for run in runs[name])
            cpu = statistics.median(run[1] for run in runs[name])
            print(f"{name}: {walls[name]:.3f} s ({cpu:.3f} s CPU)")
        slowest = max(wall for name, wall in walls.items() if name.startswith("rasm"))
        bare = walls["rasm check p.rv t.jsonl"] / walls["python -c pass"]
        print(f"rasm check p.rv t.jsonl over python -c pass: {bare:.1f}x")
        cold = statistics.median(  # each run with a cache folder of its own, empty
            timed(commands["rasm check p.rv t.jsonl"], work,
                  {**env, "XDG_CACHE_HOME": str(work / f"cache{k}")})[0]
            for k in range(repeats)
        )
        print(f"rasm check p.rv t.jsonl, caches empty (parser, specification): {cold:.3f} s")
        pytest_only, with_plugin = (
            statistics.median(timed([sys.executable, "-c", code], work, env)[0]
                              for _ in range(repeats))
            for code in ("import pytest", "import pytest, rasm.testing.plugin")
        )
        print(f"import pytest: {pytest_only:.3f} s; with rasm.testing.plugin: {with_plugin:.3f} s")
        return slowest, with_plugin - pytest_only, bare


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, one repetition")
    paths = ["hour", "check", "check-late", "start-up"]
    parser.add_argument("--only", choices=paths, action="append",
                        help="measure only this path (repeatable; default: all)")
    args = parser.parse_args()
    only = set(args.only or paths)
    repeats = 1 if args.quick else 3
    ratios = []
    if "hour" in only:
        hour = simulated_hour(repeats, 600 if args.quick else 3600)
        ratios.append(f"defaults_over_memory={hour:.2f}")
    if "check" in only:
        speed, megabytes = large_check(repeats, 200_000 if args.quick else 1_000_000)
        ratios += [f"check_over_reelay={speed:.2f}", f"check_peak_mb={megabytes:.0f}"]
    if "check-late" in only:
        megabytes, ratio = late_violation(repeats, 200_000 if args.quick else 1_000_000)
        ratios += [f"check_late_peak_mb={megabytes:.0f}", f"check_late_over_holds={ratio:.2f}"]
    if "start-up" in only:
        slowest, plugin, bare = start_up(1 if args.quick else 9)
        ratios += [f"slowest_command_s={slowest:.3f}", f"plugin_import_s={plugin:.3f}",
                   f"check_over_bare_python={bare:.1f}"]
    print("\n".join(ratios))


if __name__ == "__main__":
    main()
