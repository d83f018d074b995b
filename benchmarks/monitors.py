"""Monitor throughput: rasm against reelay and rtamt on the same properties and traces.

Run:  .venv/bin/python benchmarks/monitors.py            (1e5-record traces)
      .venv/bin/python benchmarks/monitors.py --quick    (2e4 records, one repetition)
      .venv/bin/python benchmarks/monitors.py --intervals (only: step with robustness intervals)

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
import contextlib
import io
import json
import random
import statistics
import sys
import tempfile
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


# Robustness (SPEC §12): (name, rasm, mstlo-python, rtamt) over floats x, y in [-1, 1].
# mstlo-python has future operators only (None: no such formula there); mstlo's ``until``
# also takes the left operand at the right one's position, so its values differ from rasm's
# and rtamt's there (the work is the same).
ROBUST = [
    ("historically (x <= 0.5)", "historically (x <= 0.5)", None, "historically(x <= 0.5)"),
    ("historically (y > 0.5 -> once[0,10] x > 0.5)",
     "historically (y > 0.5 -> once[0, 10] (x > 0.5))", None,
     "historically((not (y > 0.5)) or once[0:10](x > 0.5))"),
    ("x > 0.5 -> eventually[0,10] y > 0.5", "x > 0.5 -> eventually[0, 10] (y > 0.5)",
     "(x > 0.5) -> F[0,10](y > 0.5)", "(not (x > 0.5)) or eventually[0:10](y > 0.5)"),
    # mstlo's published formulas
    ("always[0,1000](x > 0.5 -> eventually[0,100] x < 0)",
     "always[0, 1000] (x > 0.5 -> eventually[0, 100] (x < 0))",
     "G[0,1000]((x > 0.5) -> F[0,100](x < 0))",
     "always[0:1000]((not (x > 0.5)) or eventually[0:100](x < 0))"),
    ("(x > -0.9) until[0,100] (y > 0.9)", "(x > -0.9) until[0, 100] (y > 0.9)",
     "(x > -0.9) U[0,100] (y > 0.9)", "(x > -0.9) until[0:100] (y > 0.9)"),
]
ROBUST_HEADER = "input x: float\ninput y: float\n"


def robust_trace(n: int, seed: int = 1) -> list[dict]:
    rng = random.Random(seed)
    return [{"time": k, "x": rng.uniform(-1, 1), "y": rng.uniform(-1, 1)} for k in range(n)]


def _budgeted(update, rows, budget: float) -> float:
    """Records per CPU second of ``update(k, row)`` over ``rows``, stopping after ``budget``."""
    start = time.process_time()
    done = 0
    for k, row in enumerate(rows):
        update(k, row)
        done = k + 1
        if done % 100 == 0 and time.process_time() - start > budget:
            break
    return done / (time.process_time() - start)


def measure_robust(formula: str, theirs: str | None, rt: str, trace: list[dict], n_rtamt: int,
                   repeat: int, work: Path, no_rtamt: bool = False,
                   budget: float = 2.0) -> dict[str, float | None]:
    """Median rates (records per CPU second) of every path, the repetitions interleaved:
    rasm ``run``, ``step`` and ``rasm check --robustness`` on a JSONL file; mstlo-python's
    ``update`` per signal, in memory and from ``json.loads`` of the same file; rtamt offline
    (``evaluate``), online (``update``, after ``pastify()`` for a future formula) and online
    from the file (rtamt on the first ``n_rtamt`` records, at most ``budget`` s a run)."""
    text = ROBUST_HEADER + f"property p: {formula}\n"
    props = work / "robust.rv"
    props.write_text(text)
    big, small = work / "robust.jsonl", work / "robust_rtamt.jsonl"
    records = [(r["time"], {"x": r["x"], "y": r["y"]}) for r in trace]
    rates: dict[str, list[float]] = {k: [] for k in (
        "run", "step", "check", "mstlo", "mstlo file", "rtamt off", "rtamt on", "rtamt file")}
    future = "eventually" in rt or "always" in rt or "until" in rt
    parsed = None
    if theirs is not None:
        import mstlo_python as mstlo

        parsed = mstlo.parse_formula(theirs)
    few = trace[:n_rtamt]
    dataset = {"time": [r["time"] for r in few], "x": [r["x"] for r in few],
               "y": [r["y"] for r in few]}
    rows = [[("x", r["x"]), ("y", r["y"])] for r in few]
    for _ in range(repeat):
        batch = compile_properties(text, robustness=True)
        rates["run"].append(timed(lambda m=batch: m.run(records), len(records)))
        online = compile_properties(text, robustness=True)

        def step(monitor=online):
            feed = monitor.step
            for t, values in records:
                feed(t, values)
            monitor.finish()

        rates["step"].append(timed(step, len(records)))
        argv = ["check", str(props), str(big), "--robustness", "--format", "json", "--jobs", "1"]

        def check(argv=argv):
            from rasm.cli import main as rasm_main

            with contextlib.redirect_stdout(io.StringIO()):
                rasm_main(argv)

        rates["check"].append(timed(check, len(records)))
        if parsed is not None:

            def peer(formula=parsed):
                update = mstlo.Monitor(formula, semantics="DelayedQuantitative").update
                for r in trace:
                    t = float(r["time"])
                    update("x", r["x"], t)
                    update("y", r["y"], t)

            rates["mstlo"].append(timed(peer, len(trace)))

            def peer_file(formula=parsed):
                update = mstlo.Monitor(formula, semantics="DelayedQuantitative").update
                with big.open() as lines:
                    for line in lines:
                        r = json.loads(line)
                        t = float(r.pop("time"))
                        for name, value in r.items():
                            update(name, value, t)

            rates["mstlo file"].append(timed(peer_file, len(trace)))
        if no_rtamt:
            continue
        import rtamt

        def spec(online: bool):
            s = rtamt.StlDiscreteTimeSpecification()
            s.declare_var("x", "float")
            s.declare_var("y", "float")
            s.spec = rt
            s.parse()
            if online and future:
                s.pastify()
            return s

        offline = spec(False)
        rates["rtamt off"].append(timed(lambda s=offline: s.evaluate(dataset), len(few)))
        rates["rtamt on"].append(_budgeted(spec(True).update, rows, budget))

        def from_file(update):
            start = time.process_time()
            done = 0
            with small.open() as lines:
                for k, line in enumerate(lines):
                    r = json.loads(line)
                    del r["time"]
                    update(k, list(r.items()))
                    done = k + 1
                    if done % 100 == 0 and time.process_time() - start > budget:
                        break
            return done / (time.process_time() - start)

        rates["rtamt file"].append(from_file(spec(True).update))
    return {k: statistics.median(v) if v else None for k, v in rates.items()}


def robustness_section(n: int, n_rtamt: int, repeat: int, no_rtamt: bool) -> list[tuple]:
    """The robustness table: rasm against mstlo-python and rtamt (see :data:`ROBUST`)."""
    trace = robust_trace(n)
    print()
    print(f"robustness: {n} records (rtamt: {n_rtamt}); median of {repeat}")
    columns = ("case", "rasm run", "rasm step", "rasm check", "mstlo", "mstlo file",
               "rtamt off", "rtamt on", "rtamt file", "run/mstlo", "step/mstlo",
               "check/mstlo file", "run/rtamt off", "step/rtamt on", "check/rtamt file")
    print(" | ".join(columns))
    rows = []
    import rasm.cli  # noqa: F401  (imported before timing: rasm check's start-up is not timed)

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for path, part in ((work / "robust.jsonl", trace),
                           (work / "robust_rtamt.jsonl", trace[:n_rtamt])):
            with path.open("w") as out:
                for r in part:
                    out.write(json.dumps(r) + "\n")
        for name, mine, theirs, rt in ROBUST:
            r = measure_robust(mine, theirs, rt, trace, n_rtamt, repeat, work, no_rtamt)
            row = (name, *(fmt(r[k]) for k in ("run", "step", "check", "mstlo", "mstlo file",
                                              "rtamt off", "rtamt on", "rtamt file")),
                   ratio(r["run"], r["mstlo"]), ratio(r["step"], r["mstlo"]),
                   ratio(r["check"], r["mstlo file"]), ratio(r["run"], r["rtamt off"]),
                   ratio(r["step"], r["rtamt on"]), ratio(r["check"], r["rtamt file"]))
            print(" | ".join(row), flush=True)
            rows.append((name, r))
    return rows


# (name, formula over x and y with the bound b in seconds): early verdicts with intervals
INTERVALS = [
    ("x > 0.5 -> eventually[0,b] y > 0.55", "x > 0.5 -> eventually[0, {b}s] (y > 0.55)"),
    ("eventually[1,b] x > 0.9", "eventually[1s, {b}s] (x > 0.9)"),
]
INTERVAL_MODES = (("no intervals", False), ('intervals="newest"', "newest"),
                  ("intervals=True", True))


def intervals_section(n: int, repeat: int, bounds: tuple[int, ...] = (1, 10, 100),
                      budget: float = 2.0) -> list[tuple]:
    """``Monitor.step`` with robustness at 10 Hz, in µs per record, without intervals, with the
    loop's ``intervals="newest"`` (flat in the bound) and with every interval (``True``: in
    proportion to the records open; at most ``budget`` CPU seconds a run)."""
    rng = random.Random(1)
    records = [(k / 10, {"x": rng.random(), "y": rng.random()}) for k in range(n)]
    print()
    print(f"robustness intervals: step at 10 Hz, {n} records, µs per record, median of {repeat}")
    print(" | ".join(("case", "b (s)", *(label for label, _ in INTERVAL_MODES))))
    rows = []
    for name, formula in INTERVALS:
        for b in bounds:
            text = ROBUST_HEADER + f"property p: {formula.format(b=b)}\n"
            costs = {}
            for label, mode in INTERVAL_MODES:
                rates = []
                for _ in range(repeat):
                    monitor = compile_properties(text, robustness=True, intervals=mode)
                    rates.append(_budgeted(lambda k, r, s=monitor.step: s(*r), records, budget))
                costs[label] = 1e6 / statistics.median(rates)
            print(" | ".join((name, str(b), *(f"{costs[label]:.1f}" for label, _ in
                                              INTERVAL_MODES))), flush=True)
            rows.append((name, b, costs))
    return rows


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
    return statistics.median(_budgeted(build().update, rows, budget) for _ in range(repeat))


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
    parser.add_argument("--robustness", action="store_true",
                        help="only the robustness table (rasm against mstlo-python and rtamt)")
    parser.add_argument("--intervals", action="store_true",
                        help="only the table of step with robustness intervals (b = 1, 10, 100)")
    args = parser.parse_args(argv)
    n = args.records or (20_000 if args.quick else 100_000)
    n_rtamt = args.rtamt_records or (2_000 if args.quick else 10_000)
    repeat = args.repeat or (1 if args.quick else 3)
    bounds = [int(b) for b in args.bounds.split(",")]
    if args.robustness:
        robustness_section(n, n_rtamt, repeat, args.no_rtamt)
        return 0
    if args.intervals:
        intervals_section(n, repeat)
        return 0

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
    robustness_section(n, n_rtamt, repeat, args.no_rtamt)
    intervals_section(n, repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
