"""Chart verification speed: ``rasm verify`` against a brute-force search over stock sismic.

Three measurements (figures in docs/verify.md):

- **states per second**: rasm's exploration against a breadth-first search over deep copies of
  stock sismic interpreters (``tests/verify/reference.py``: keyed by configuration, context and
  history memory), on the same charts with the same events. The brute force stops at
  ``--brute-states`` states (a chart with a counter nobody tests never ends for it); rasm
  explores completely. Both rates are distinct states found per second of CPU.
- **time to verify** every chart of ``statecharts/`` (goal: each under 10 s) under its default
  environment, as ``rasm verify`` runs it.
- **time to the first counterexample** on planted-bug charts (the bug needs seven or more
  events, or a timer): ``rasm verify`` against ``rasm.testing.statechart_machine`` with its
  default budget (hypothesis' default examples and 20 steps), which samples event sequences.

Run: ``.venv/bin/python benchmarks/verify.py [--quick]``; the last line is
``min_ratio=X.X`` (the smallest states-per-second ratio).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rasm.resources import data_dir  # noqa: E402
from rasm.statechart import load_statechart  # noqa: E402
from rasm.verify import EnvEvent, Environment, verify_chart  # noqa: E402
from rasm.verify.code import analyse_chart  # noqa: E402
from rasm.verify.explore import ChartExplorer, explore  # noqa: E402
from tests.verify.reference import brute_force  # noqa: E402


def grid(regions: int = 4, size: int = 5) -> str:
    """``regions`` parallel cycles of ``size`` states, each on its own event, and a shared
    ``reset`` that counts modulo 3: size**regions * 3 states at most."""
    parts = []
    for r in range(regions):
        states = "\n".join(
            f"          - name: r{r}s{k}\n            transitions:\n"
            f"              - {{target: r{r}s{(k + 1) % size}, event: e{r}}}\n"
            f"              - target: r{r}s0\n                event: reset\n"
            f"                guard: x < 2\n                action: x = (x + 1) % 3"
            for k in range(size)
        )
        parts.append(f"      - name: r{r}\n        initial: r{r}s0\n        states:\n{states}")
    return (
        "statechart:\n  name: grid\n  preamble: x = 0\n  root state:\n    name: root\n"
        "    parallel states:\n" + "\n".join(parts) + "\n"
    )


LOCK = (ROOT / "tests" / "verify" / "test_counterexamples.py").read_text().split('LOCK = """')[1]
LOCK = LOCK.split('"""')[0]


def cpu(func):
    start = time.process_time()
    result = func()
    return result, time.process_time() - start


def states_per_second(path: Path, brute_states: int, runs: int) -> tuple[float, float, int, int]:
    statechart = load_statechart(path)
    names = analyse_chart(statechart).events
    env = Environment(tuple(EnvEvent(n) for n in names))
    ours, theirs = [], []
    for _ in range(runs):
        found, seconds = cpu(lambda: explore(ChartExplorer(statechart, env)))
        ours.append(found.states / seconds)

        def search():
            try:
                return brute_force(statechart, [(n, {}) for n in names], max_states=brute_states)[1]
            except RuntimeError:  # its budget: a chart whose context grows without bound
                return brute_states
        count, seconds = cpu(search)
        theirs.append(count / seconds)
    return statistics.median(ours), statistics.median(theirs), found.states, count


def first_counterexample_rasm(chart: Path) -> tuple[float, int]:
    env = chart.with_suffix(".env.yaml")
    props = chart.with_suffix(".rv")
    result, seconds = cpu(lambda: verify_chart(chart, environment=env, properties=props))
    (prop,) = result.properties
    assert prop.verdict == "violated"
    return seconds, len(prop.counterexample.moves)


def first_counterexample_sampling(chart: Path) -> float | None:
    """statechart_machine with its default budget: seconds to a failure, None if none found."""
    from hypothesis import settings
    from hypothesis.stateful import run_state_machine_as_test

    from rasm.testing import statechart_machine

    events = {"key": {"digit": 0}, "push": None, "pull": None, "reset": None}
    machine = statechart_machine(
        chart, events=events, invariant=lambda state: not state.active("alarm")
    )
    start = time.process_time()
    try:
        run_state_machine_as_test(machine, settings=settings(database=None, deadline=None))
    except Exception:
        return time.process_time() - start
    return None


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--brute-states", type=int, default=2000)
    args = parser.parse_args()
    runs = 1 if args.quick else 3
    import tempfile

    folder = Path(tempfile.mkdtemp())
    (folder / "grid.yaml").write_text(grid())
    charts = [*sorted(data_dir("statecharts").glob("*.yaml")), folder / "grid.yaml"]

    print("states per second (CPU): rasm verify against a brute force over stock sismic")
    print(f"{'chart':<26} {'rasm':>8} {'brute':>8} {'ratio':>6}  states: rasm (complete), brute")
    ratios = []
    for path in charts:
        ours, theirs, n, m = states_per_second(path, args.brute_states, runs)
        ratios.append(ours / theirs)
        brute = f"{m}" if m < args.brute_states else f"{m} (stopped: never completes)"
        print(f"{path.stem:<26} {ours:>8.0f} {theirs:>8.0f} {ours / theirs:>6.1f}  {n}, {brute}")

    print("\ntime to verify each platform chart (default environment, CPU seconds)")
    worst = 0.0
    for path in charts[:-1]:
        result, seconds = cpu(lambda path=path: verify_chart(path))
        worst = max(worst, seconds)
        print(f"{path.stem:<34} {seconds:>7.3f} s  {result.verdict}, {result.states} states")
    print(f"slowest: {worst:.3f} s (goal: under 10 s)")

    print("\ntime to the first counterexample: the combination lock (7 keys, a push, 3 s)")
    lock = folder / "lock.yaml"
    lock.write_text(LOCK)
    lock.with_suffix(".env.yaml").write_text(
        "events:\n  - name: key\n    data: {digit: [1, 2, 3, 4, 5, 9]}\n  - push\n  - pull\n"
        "  - reset\nclock: [0.5, 1]\n"
    )
    lock.with_suffix(".rv").write_text('property no_alarm: always not in_state("alarm")\n')
    seconds, moves = first_counterexample_rasm(lock)
    print(f"rasm verify: {seconds:.2f} s CPU, a counterexample of {moves} moves")
    sampled = first_counterexample_sampling(lock)
    print("statechart_machine (default budget): " + (
        f"{sampled:.2f} s CPU" if sampled is not None else "no counterexample found"
    ))
    print(f"\nmin_ratio={min(ratios):.1f}")


if __name__ == "__main__":
    main()
