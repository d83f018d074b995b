"""The TurtleBot occlusion demonstrator with and without its adaptation loop.

Run:  .venv/bin/python benchmarks/turtlebot.py               (50 scenarios, the plot)
      .venv/bin/python benchmarks/turtlebot.py --seeds 10    (fewer)

Each seed generates a scenario (``tb4.world.generate_scenario``: two or three obstacles on the
route, wide debris ahead from 0.5-1.5 s, in 40 % of them more debris next to it later) and runs
it on the simulated clock for 90 s in four conditions: the same loop whose Plan stage plans
nothing (occlusions are found, nothing is done); the MAPLE-K loop without looks for clearance;
the loop that looks once ``keeps_clearance`` is violated (boolean); the loop as shipped, which
looks when its robustness, now or 0.5 s ahead, falls below 0.3 m (predictive). Reported per
condition: collisions (total, and runs with any), goals reached, time to goal (median, over runs
that reach it), the runs where ``keeps_clearance`` (or any other property) is not satisfied, the
looks for clearance and when the first one comes (boolean against predictive, on the scenarios
where both look), the least robustness of ``keeps_clearance`` while the robot drives, and for
the shipped loop the latencies: debris onset -> anomaly (detection, simulated s), anomaly ->
executed (simulated s) and the loop's compute time for that iteration (wall ms, the
sum of its stage durations). On the simulated clock the stages take no simulated time, so
anomaly -> executed is 0 there; ``--live N`` adds N short wall-clock runs for the live figure.
``--plot`` (default ``docs/images/turtlebot.png``) draws the
per-seed collisions and times to goal; it needs matplotlib (``pip install rasm[docs]``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples" / "turtlebot"))

from tb4.evaluation import APP, Outcome, run  # noqa: E402

from rasm.platform.manifest import load_manifest  # noqa: E402

DEFAULT_SCENARIO = load_manifest(APP).scenario


# condition: (name in the tables, with the loop's plans, when it looks for clearance)
CONDITIONS = {
    "none": ("without the loop", False, "predictive"),
    "off": ("the loop, no looks for clearance", True, "off"),
    "boolean": ("the loop, looks once keeps_clearance is violated", True, "boolean"),
    "predictive": ("the loop as shipped (predictive looks)", True, "predictive"),
}


def _one(args: tuple[int, str]) -> tuple[int, str, Outcome]:
    seed, condition = args
    _, loop, look = CONDITIONS[condition]
    return seed, condition, run(seed, loop=loop, look=look, duration=90.0)


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def _pct(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def summarise(outcomes: dict[str, list[Outcome]]) -> list[str]:
    """The markdown tables of docs/turtlebot.md."""
    lines = [
        "| condition | runs | collisions | runs with a collision | goals reached "
        "| time to goal, median (s) | `keeps_clearance` violated (runs) | other properties "
        "not satisfied (runs) | looks for clearance |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for condition, (name, _, _) in CONDITIONS.items():
        out = outcomes[condition]
        reached = [o.time_to_goal for o in out if o.reached]
        lines.append(
            f"| {name} | {len(out)} | {sum(o.collisions for o in out)} "
            f"| {sum(1 for o in out if o.collisions)} | {len(reached)} "
            f"| {_median(reached):.1f} | {sum(1 for o in out if 'keeps_clearance' in o.failed)} "
            f"| {sum(1 for o in out if set(o.failed) - {'keeps_clearance'})} "
            f"| {sum(len(o.looks) for o in out)} |"
        )
    late, early = outcomes["boolean"], outcomes["predictive"]
    pairs = [(b.looks[0], p.looks[0]) for b, p in zip(late, early, strict=True)
             if b.looks and p.looks]
    ahead = [b - p for b, p in pairs]
    least = {c: [o.least_robustness for o in outcomes[c] if o.least_robustness is not None]
             for c in ("boolean", "predictive")}
    lines += [
        "",
        "| first look for clearance | runs | predictive earlier | by, median (s) | min | max |",
        "|---|---|---|---|---|---|",
        f"| boolean against predictive, where both look | {len(pairs)} "
        f"| {sum(1 for a in ahead if a > 0)} | {_median(ahead):.1f} "
        f"| {min(ahead, default=float('nan')):.1f} | {max(ahead, default=float('nan')):.1f} |",
        "",
        "| least robustness of keeps_clearance while driving (m) | runs | min | median |",
        "|---|---|---|---|",
        *(f"| {c} | {len(v)} | {min(v, default=float('nan')):.3f} | {_median(v):.3f} |"
          for c, v in least.items()),
    ]
    out = outcomes["predictive"]
    detection = [d for o in out for d in o.detection]
    act = [d for o in out for d in o.detect_to_act]
    compute = [c * 1000 for o in out for c in o.loop_compute]
    lines += [
        "",
        "| latency (with the loop) | n | median | p90 | max |",
        "|---|---|---|---|---|",
        f"| debris onset -> anomaly (s, simulated) | {len(detection)} | {_median(detection):.2f} "
        f"| {_pct(detection, 0.9):.2f} | {max(detection, default=float('nan')):.2f} |",
        f"| anomaly -> executed (s, simulated) | {len(act)} | {_median(act):.2f} "
        f"| {_pct(act, 0.9):.2f} | {max(act, default=float('nan')):.2f} |",
        f"| loop compute for that iteration (ms, wall) | {len(compute)} | {_median(compute):.1f} "
        f"| {_pct(compute, 0.9):.1f} | {max(compute, default=float('nan')):.1f} |",
    ]
    return lines


def plot(outcomes: dict[str, list[Outcome]], seeds: list[int], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    styles = (("none", "tab:red", "o", "without the loop"),
              ("predictive", "tab:blue", "s", "with the loop"))
    for condition, colour, marker, label in styles:
        out = outcomes[condition]
        offset = 0.15 if condition == "predictive" else -0.15
        left.scatter(
            [s + offset for s in seeds],
            [o.collisions for o in out],
            s=16,
            color=colour,
            marker=marker,
            label=label,
        )
        reached = [(s, o.time_to_goal) for s, o in zip(seeds, out, strict=True) if o.reached]
        right.scatter(
            [s for s, _ in reached],
            [t for _, t in reached],
            s=14,
            color=colour,
            marker=marker,
            label=label,
        )
    left.yaxis.get_major_locator().set_params(integer=True)
    left.set(xlabel="scenario seed", ylabel="collisions", title="Collisions per scenario")
    right.set(
        xlabel="scenario seed", ylabel="time to goal (s)", title="Time to goal (runs that reach it)"
    )
    for ax in (left, right):
        ax.grid(alpha=0.3)
    handles, labels = left.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=9)
    fig.suptitle("TurtleBot 4 with LiDAR debris: the MAPLE-K loop stops and looks around")
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def simulate(seeds: list[int], jobs: int) -> dict[str, list[Outcome]]:
    """Every seed in every condition, on the simulated clock, ``jobs`` at a time."""
    results: dict[tuple[int, str], Outcome] = {}
    with ProcessPoolExecutor(jobs) as pool:
        for seed, condition, outcome in pool.map(_one, [(s, c) for s in seeds for c in CONDITIONS]):
            results[(seed, condition)] = outcome
            print(
                f"seed {seed:3d} {condition:10s}: {outcome.collisions} collisions, "
                + (f"goal at {outcome.time_to_goal:.1f} s" if outcome.reached else "no goal")
                + (f", not satisfied: {', '.join(outcome.failed)}" if outcome.failed else "")
                + (f", first look {outcome.looks[0]:.1f} s" if outcome.looks else ""),
                file=sys.stderr,
                flush=True,
            )
    return {c: [results[(s, c)] for s in seeds] for c in CONDITIONS}


def live(runs: int, seconds: float = 5.0) -> str:
    """Anomaly -> executed on the wall clock (local bus): the detect-to-act latency a live loop
    sees, over ``runs`` short runs of the default scenario's first debris."""
    latencies = []
    for seed in range(runs):
        outcome = run(seed, duration=seconds, scenario=DEFAULT_SCENARIO, clock="wall")
        latencies += [d * 1000 for d in outcome.detect_to_act]
    return (
        f"| anomaly -> executed, live (ms, wall clock, {runs} runs) | {len(latencies)} "
        f"| {_median(latencies):.1f} | {_pct(latencies, 0.9):.1f} "
        f"| {max(latencies, default=float('nan')):.1f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--plot", type=Path, default=ROOT / "docs" / "images" / "turtlebot.png")
    parser.add_argument("--no-plot", action="store_true")
    parser.add_argument("--live", type=int, default=5, help="wall-clock runs for the latency")
    parser.add_argument("--save", type=Path, help="write the outcomes to this JSON file")
    parser.add_argument("--load", type=Path, help="table and plot from saved outcomes")
    args = parser.parse_args()
    if args.load:
        saved = json.loads(args.load.read_text())
        seeds = saved["seeds"]
        outcomes = {c: [Outcome(**o) for o in saved[c]] for c in CONDITIONS}
    else:
        seeds = list(range(args.seeds))
        outcomes = simulate(seeds, args.jobs)
    if args.save:
        args.save.write_text(
            json.dumps(
                {"seeds": seeds} | {k: [asdict(o) for o in v] for k, v in outcomes.items()}
            )
        )
    print("\n".join(summarise(outcomes)))
    if args.live:
        print("\n" + live(args.live))
    if not args.no_plot:
        plot(outcomes, seeds, args.plot)
        print(f"\nplot: {args.plot}")


if __name__ == "__main__":
    main()
