"""Monitor throughput: rasm against reelay and rtamt on the same properties and traces.

Run:  .venv/bin/python benchmarks/monitors.py            (1e5-record traces)
      .venv/bin/python benchmarks/monitors.py --quick    (2e4 records, one repetition)

Every tool gets the same records (discrete time: record k at time k, every signal set on every
record) and produces one verdict per record. Reported, in events (records) per second:

* ``rasm run``  — ``Monitor.run(records)``, the offline path of ``rasm check``;
  compiling (~5–10 ms) is not timed, as building reelay's and rtamt's monitors is not;
* ``rasm step`` — ``Monitor.step(t, values)`` once per record, the online path (a list of
  ``Verdict`` objects per call);
* the classic properties again on a 10 Hz trace whose times are floats (k / 10), each
  converted to exact nanoseconds per record (``BASIC_10HZ``), against reelay on the same
  records;
* properties whose operators get their operands' values late and in any order (``LATE``;
  no peer monitors them online), on the same trace;
* properties that read ``time`` (``TIME_READING``; no peer has that expression) on the same
  trace at 10 Hz, times k / 10, beside the same shapes over a signal: what exact time costs;
* ``reelay``    — ``reelay.discrete_timed_monitor(pattern, condense=False).update(record)``;
* ``rtamt``     — ``StlDiscreteTimeSpecification.update(k, [(name, value), …])`` (past
  formulas directly; the future one after ``pastify()``). rtamt is slow, so it runs on the
  first ``--rtamt-records`` records only, and at most ~2 s per run (its bounded ``since``
  costs O(bound) per record); its rate is still events per second.

Each figure is the median of ``--repeat`` runs, in records per second of this process's CPU
time; rasm's and reelay's runs are interleaved so that load on a shared machine hits them
alike. Ratios are rasm's rate over the peer's.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import monitors_timescales as timescales  # noqa: E402

from rasm.properties import compile_properties  # noqa: E402

BASIC = [
    # (name, rasm, reelay, rtamt); signals x (float), a, b (bool)
    ("historically (x <= 0.5)", "historically (x <= 0.5)", "historically({x <= 0.5})",
     "historically(x <= 0.5)"),
    ("historically (b -> once[0,10] a)", "historically (b -> once[0, 10] a)",
     "historically({b} -> once[0:10]{a})",
     "historically((not (b >= 0.5)) or once[0:10](a >= 0.5))"),
    ("a -> eventually[0,10] b", "a -> eventually[0, 10] b", None,
     "(not (a >= 0.5)) or eventually[0:10](b >= 0.5)"),
]

# The same properties on the 10 Hz trace (times k / 10, floats: each converted exactly to
# nanoseconds per record), their bounds in seconds a tenth of the above, so that reelay's
# pattern (which counts records) computes the same verdicts.
BASIC_10HZ = [
    ("historically (x <= 0.5) (10 Hz)", "historically (x <= 0.5)", "historically({x <= 0.5})"),
    ("historically (b -> once[0,1] a) (10 Hz)", "historically (b -> once[0, 1] a)",
     "historically({b} -> once[0:10]{a})"),
    ("a -> eventually[0,1] b (10 Hz)", "a -> eventually[0, 1] b", None),
]

# Properties that read ``time`` (no peer has such an expression): on a 10 Hz trace whose times
# are decimals (k / 10), beside the same shapes over a signal, for the cost of exact time.
TIME_READING = [
    "time - prev(time) <= 0.1",
    "x - prev(x) <= 0.1",
    "historically (a -> time >= 5)",
    "historically (a -> x >= 0.05)",
    "a -> eventually[0, 1] (b and time - prev(time) <= 0.1)",
]


# operators whose operands' values come late, and in any order (no peer monitors these online)
LATE = [
    "(always[0, 3] (x <= 0.5)) and (eventually[0, 50] b)",
    "a -> eventually[0, 10] (b and always[0, 2] (x <= 0.5))",
    "eventually[0, 5] (always[0, 2] b)",
    "once[0, 10] (eventually[0, 5] b)",
    "(eventually[0, 2] a) until[0, 10] (b)",
    "count[0, 10](eventually[0, 5] b) >= 2",
]


def basic_trace(n: int, seed: int = 1) -> list[dict]:
    rng = random.Random(seed)
    return [
        {"time": k, "x": rng.random() * 0.52, "a": rng.random() < 0.3, "b": rng.random() < 0.3}
        for k in range(n)
    ]


def decimal_trace(n: int, seed: int = 1) -> list[dict]:
    """The basic trace at 10 Hz: record k at time k / 10 (the float of the decimal)."""
    return [{**record, "time": record["time"] / 10} for record in basic_trace(n, seed)]


def timed(function, n: int) -> float:
    """Records per second of this process's CPU time: on a shared machine, the time spent
    waiting for a core would count against whichever tool it fell on."""
    start = time.process_time()
    function()
    return n / (time.process_time() - start)


def measure_case(header: str, formula: str, pattern: str | None, trace: list[dict],
                 repeat: int) -> tuple[float, float, float | None]:
    """Median rates of rasm run, rasm step and reelay, their repetitions interleaved.

    Interleaving (run, step, reelay, run, step, reelay, …) makes a load spike on a shared
    machine hit every tool alike, so the ratios stay meaningful. Building the monitors
    (``compile_properties``, ~5-10 ms; reelay's constructor) is not timed.
    """
    text = header + f"property p: {formula}\n"
    records = [(r["time"], {k: v for k, v in r.items() if k != "time"}) for r in trace]
    plain = [{k: v for k, v in r.items() if k != "time"} for r in trace]
    rates: dict[str, list[float]] = {"run": [], "step": [], "reelay": []}
    for _ in range(repeat):
        batch = compile_properties(text)
        rates["run"].append(timed(lambda m=batch: m.run(records), len(records)))
        online = compile_properties(text)

        def step(monitor=online):
            feed = monitor.step
            for t, values in records:
                feed(t, values)
            monitor.finish()

        rates["step"].append(timed(step, len(records)))
        if pattern is not None:
            import reelay

            update = reelay.discrete_timed_monitor(pattern=pattern, condense=False).update

            def peer(update=update):
                for record in plain:
                    update(record)

            rates["reelay"].append(timed(peer, len(plain)))
    reelay_rate = statistics.median(rates["reelay"]) if rates["reelay"] else None
    return statistics.median(rates["run"]), statistics.median(rates["step"]), reelay_rate


def measure_rtamt(formula: str, variables: list[str], trace: list[dict], future: bool,
                  repeat: int, budget: float = 2.0) -> float | None:
    try:
        import rtamt
    except ImportError:
        return None
    rename = {"s": "sx"}
    rows = [
        [(rename.get(v, v), float(r[v])) for v in variables] for r in trace
    ]

    def build():
        spec = rtamt.StlDiscreteTimeSpecification()
        for v in variables:
            spec.declare_var(rename.get(v, v), "float")
        spec.spec = formula
        spec.parse()
        if future:
            spec.pastify()
        return spec

    # rtamt's bounded since costs O(bound) per record: give it a time budget per run and
    # report the rate over the records it got through
    rates = []
    for _ in range(repeat):
        update = build().update
        start = time.process_time()
        done = 0
        for k, row in enumerate(rows):
            update(k, row)
            done = k + 1
            if done % 100 == 0 and time.process_time() - start > budget:
                break
        rates.append(done / (time.process_time() - start))
    return statistics.median(rates)


def flatness(name: str, bounds: list[int], trace: list[dict], repeat: int) -> list[float]:
    """rasm's best rate per bound, the bounds interleaved so that load spikes hit all alike."""
    records = [(r["time"], {k: v for k, v in r.items() if k != "time"}) for r in trace]
    texts = [timescales.RASM_HEADER + f"property p: {timescales.pattern(name, b // 2, b).rasm}\n"
             for b in bounds]
    best = [0.0] * len(bounds)
    for _ in range(repeat):
        for k, text in enumerate(texts):
            monitor = compile_properties(text)
            start = time.process_time()
            monitor.run(records)
            best[k] = max(best[k], len(records) / (time.process_time() - start))
    return best


def fmt(rate: float | None) -> str:
    if rate is None:
        return "n/a"
    if rate >= 1e6:
        return f"{rate / 1e6:.2f} M"
    if rate >= 1e4:
        return f"{rate / 1e3:.0f} k"
    return f"{rate / 1e3:.2f} k"


def ratio(a: float, b: float | None) -> str:
    return "n/a" if not b else f"{a / b:.1f}x"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2e4 records, one repetition")
    parser.add_argument("--records", type=int, default=None)
    parser.add_argument("--rtamt-records", type=int, default=None)
    parser.add_argument("--repeat", type=int, default=None)
    parser.add_argument("--bounds", default="10,100,1000")
    parser.add_argument("--no-rtamt", action="store_true")
    args = parser.parse_args(argv)
    n = args.records or (20_000 if args.quick else 100_000)
    n_rtamt = args.rtamt_records or (2_000 if args.quick else 10_000)
    repeat = args.repeat or (1 if args.quick else 3)
    bounds = [int(b) for b in args.bounds.split(",")]

    print(f"records: {n} (rtamt: {n_rtamt}); median of {repeat}; Python {sys.version.split()[0]}")
    header = ("case", "rasm run", "rasm step", "reelay", "rtamt", "run/reelay", "step/reelay",
              "run/rtamt", "step/rtamt")
    print(" | ".join(header))
    rows = []

    def report(name, run, step, reelay_rate, rtamt_rate):
        row = (name, fmt(run), fmt(step), fmt(reelay_rate), fmt(rtamt_rate),
               ratio(run, reelay_rate), ratio(step, reelay_rate), ratio(run, rtamt_rate),
               ratio(step, rtamt_rate))
        rows.append((name, run, step, reelay_rate, rtamt_rate))
        print(" | ".join(row), flush=True)

    trace = basic_trace(n)
    basic_header = "input x: float\ninput a: bool\ninput b: bool\n"
    for name, mine, theirs, rt in BASIC:
        run, step, reelay_rate = measure_case(basic_header, mine, theirs, trace, repeat)
        rtamt_rate = None if args.no_rtamt else measure_rtamt(
            rt, ["x", "a", "b"], trace[:n_rtamt], "eventually" in rt, repeat)
        report(name, run, step, reelay_rate, rtamt_rate)

    decimal = decimal_trace(n)
    for name, mine, theirs in BASIC_10HZ:
        run, step, reelay_rate = measure_case(basic_header, mine, theirs, decimal, repeat)
        report(name, run, step, reelay_rate, None)

    for formula in LATE:
        run, step, _ = measure_case(basic_header, formula, None, trace, repeat)
        report(formula, run, step, None, None)

    for formula in TIME_READING:
        run, step, _ = measure_case(basic_header, formula, None, decimal, repeat)
        report(f"{formula} (10 Hz)", run, step, None, None)

    ts_trace = timescales.trace(n, seed=1)  # one trace for every bound: flatness is comparable
    for name in timescales.PATTERNS:
        for bound in bounds:
            p = timescales.pattern(name, bound // 2, bound)
            run, step, reelay_rate = measure_case(timescales.RASM_HEADER, p.rasm, p.reelay,
                                                  ts_trace, repeat)
            rtamt_rate = None if args.no_rtamt else measure_rtamt(
                p.rtamt, ["p", "q", "r", "s"], ts_trace[:n_rtamt], False, repeat)
            report(f"{name} u={bound}", run, step, reelay_rate, rtamt_rate)

    print()
    print("flatness: rasm run, best of", repeat, "interleaved runs per bound "
          f"({' / '.join(map(str, bounds))}), slowest over fastest:")
    for name in timescales.PATTERNS:
        best = flatness(name, bounds, ts_trace, repeat)
        print(f"  {name}: {' / '.join(fmt(r) for r in best)}  ({min(best) / max(best):.2f})")
    for label, mine, peer in [("run", 1, 3), ("step", 2, 3), ("run", 1, 4), ("step", 2, 4)]:
        ratios = [(r[mine] / r[peer], r[0]) for r in rows if r[peer]]
        if ratios:
            worst = min(ratios)
            who = "reelay" if peer == 3 else "rtamt"
            print(f"lowest rasm-{label}/{who}: {worst[0]:.2f}x ({worst[1]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
