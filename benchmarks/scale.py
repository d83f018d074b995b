"""Many and large recordings: ``rasm check --jobs 1`` against ``--jobs 2``, and the peers.

Run:  .venv/bin/python benchmarks/scale.py            (8 × 2.5e5 records, one of 2e6)
      .venv/bin/python benchmarks/scale.py --quick    (8 × 5e4, one of 4e5, one repetition)
      .venv/bin/python benchmarks/scale.py --growth   (adds 1 → 100 recordings, 1e5 → 1e7 records)

Everything is end to end, as a user runs it: ``rasm check PROPS RECORDING... --format json`` as
a command (start-up, reading, checking, the report), on JSONL traces of a robot at 100 Hz
written here (velocity on every record, rare anomalies, adaptations and mode changes).

1. **Eight recordings, and one large one**: the wall time of ``--jobs 1`` (one process, one
   pass per recording: rasm's single-process path) and ``--jobs 2`` (two worker processes; the
   large trace cut into parts), each the median of ``--repeat`` interleaved runs; the speed-up
   is their ratio. The two reports are checked to be the same.
2. **Throughput against the peers' Python front ends** on the large trace: each reads the
   same file line by line with ``json.loads`` and feeds every record to its monitor —
   reelay (``discrete_timed_monitor``, past time only: the velocity limit) and rtamt
   (``StlDiscreteTimeSpecification``, the velocity limit and the timely adaptation,
   ``pastify()``-ed, on the first ``--rtamt-records`` records: it is slow); beside them
   rasm's four properties, ``--jobs 1`` and ``--jobs 2``. In records per second.
3. **Growth** (``--growth``): 1, 10 and 100 recordings of 2e4 records; one recording of 1e5,
   1e6 and 1e7 records; ``--jobs 1`` and ``--jobs 2``, one run each.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
RASM = [sys.executable, "-m", "rasm.cli"]

from tests.scale.traces import PROPS, write_trace  # noqa: E402  (the scale tests' robot trace)

CPU: list[float] = []  # the processor seconds of each check, in order


def check(props: Path, paths: list[Path], jobs: int) -> tuple[float, str]:
    """Wall seconds of ``rasm check … --jobs N --format json``, and its report; the processor
    seconds it took (its worker processes' included) go to CPU."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([*RASM, "check", str(props), *map(str, paths), "--jobs", str(jobs),
                           "--format", "json"], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    if done.returncode not in (0, 1) or done.stderr:
        raise SystemExit(f"rasm check failed ({done.returncode}): {done.stderr}")
    return seconds, done.stdout


def compare(props: Path, paths: list[Path], repeat: int) -> tuple[float, float, float, float]:
    """Median wall and processor seconds of --jobs 1 and --jobs 2 (interleaved), their reports
    compared."""
    ones, twos, cpu_ones, cpu_twos = [], [], [], []
    for _ in range(repeat):
        one, report_one = check(props, paths, 1)
        cpu_ones.append(CPU[-1])
        two, report_two = check(props, paths, 2)
        cpu_twos.append(CPU[-1])
        if report_one != report_two:
            raise SystemExit("--jobs 1 and --jobs 2 reports differ")
        ones.append(one)
        twos.append(two)
    median = statistics.median
    return median(ones), median(twos), median(cpu_ones), median(cpu_twos)


def records_of(path: Path) -> int:
    with open(path, "rb") as handle:
        return sum(1 for _ in handle)


def reelay_rate(path: Path) -> float:
    import reelay

    monitor = reelay.discrete_timed_monitor(pattern="{velocity <= 0.5}", condense=False)
    start = time.perf_counter()
    violations = n = 0
    velocity = 0.0
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            record = json.loads(line)
            velocity = record.get("velocity", velocity)  # sample and hold, as rasm does
            n += 1
            if not monitor.update({"velocity": velocity})["value"]:
                violations += 1
    return n / (time.perf_counter() - start)


def rtamt_rate(path: Path, limit: int) -> float:
    import rtamt

    spec = rtamt.StlDiscreteTimeSpecification()
    for name in ("velocity", "anomaly", "adapted"):
        spec.declare_var(name, "float")
    # 100 Hz: 2 s is 200 steps; rtamt's implication is wrong once pastified (NOTES), so "or"
    # the formula at every step (update returns its robustness there, as rasm's verdict)
    spec.spec = ("(velocity <= 0.5) and "
                 "((not (anomaly >= 0.5)) or eventually[0:200](adapted >= 0.5))")
    spec.parse()
    spec.pastify()
    start = time.perf_counter()
    n = 0
    velocity = 0.0
    with open(path, encoding="utf-8") as handle:
        for k, line in enumerate(handle):
            if k == limit:
                break
            record = json.loads(line)
            velocity = record.get("velocity", velocity)
            spec.update(k, [("velocity", velocity), ("anomaly", float(record.get("anomaly", 0))),
                            ("adapted", float(record.get("adapted", 0)))])
            n += 1
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--growth", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--rtamt-records", type=int, default=100_000)
    args = parser.parse_args()
    small, large = (50_000, 400_000) if args.quick else (250_000, 2_000_000)
    repeat = 1 if args.quick else args.repeat
    with tempfile.TemporaryDirectory() as folder:
        here = Path(folder)
        props = here / "props.rv"
        props.write_text(PROPS, encoding="utf-8")
        eight = [write_trace(here / f"robot{k}.jsonl", small, seed=k) for k in range(8)]
        big = write_trace(here / "large.jsonl", large, seed=99)
        mb = sum(p.stat().st_size for p in eight) / 1e6
        print(f"eight recordings of {small:,} records ({mb:.0f} MB), one of {large:,} "
              f"({big.stat().st_size / 1e6:.0f} MB); median of {repeat}")
        for label, paths, records in (("eight recordings", eight, 8 * small),
                                      ("one large recording", [big], large)):
            one, two, cpu_one, cpu_two = compare(props, paths, repeat)
            print(f"  {label:20} --jobs 1 {one:6.2f} s ({records / one / 1e3:5.0f} k records/s)"
                  f"  --jobs 2 {two:6.2f} s ({records / two / 1e3:5.0f} k records/s)"
                  f"  speed-up {one / two:.2f}x")
            # on a machine shared with other work the wall times say little: the processor
            # seconds say what two idle cores would give (the work split evenly)
            print(f"  {'':20} processor time: --jobs 1 {cpu_one:6.2f} s, --jobs 2 "
                  f"{cpu_two:6.2f} s; on two idle cores: {2 * cpu_one / cpu_two:.2f}x")
        print("end-to-end throughput on the large recording (records/s, reading included)")
        one, _ = check(props, [big], 1)
        two, _ = check(props, [big], 2)
        print(f"  rasm --jobs 1 (4 properties)          {large / one / 1e3:7.0f} k")
        print(f"  rasm --jobs 2 (4 properties)          {large / two / 1e3:7.0f} k")
        print(f"  reelay (velocity limit)               {reelay_rate(big) / 1e3:7.0f} k")
        limit = min(args.rtamt_records, large)
        print(f"  rtamt (limit and adaptation, first {limit:,}) "
              f"{rtamt_rate(big, limit) / 1e3:5.0f} k")
        if args.growth:
            growth(here, props)


def growth(here: Path, props: Path) -> None:
    print("growth: recordings of 20,000 records")
    pool = [write_trace(here / f"g{k}.jsonl", 20_000, seed=k) for k in range(100)]
    for count in (1, 10, 100):
        one, _ = check(props, pool[:count], 1)
        two, _ = check(props, pool[:count], 2)
        print(f"  {count:3} recordings  --jobs 1 {one:7.2f} s  --jobs 2 {two:7.2f} s")
    print("growth: one recording")
    for records in (100_000, 1_000_000, 10_000_000):
        path = write_trace(here / f"n{records}.jsonl", records, seed=1)
        one, _ = check(props, [path], 1)
        two, _ = check(props, [path], 2)
        print(f"  {records:>10,} records  --jobs 1 {one:7.2f} s ({records / one / 1e3:4.0f} k/s)"
              f"  --jobs 2 {two:7.2f} s ({records / two / 1e3:4.0f} k/s)")
        path.unlink()


if __name__ == "__main__":
    main()
