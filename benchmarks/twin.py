"""The Hotbox with and without its digital twin, on seeded scenarios with content changes.

Run:  .venv/bin/python benchmarks/twin.py                 (20 scenarios, the plot)
      .venv/bin/python benchmarks/twin.py --seeds 5       (fewer)

Each seed draws a scenario: lid openings (the first after 5-15 s, then every 20-40 s, each
6-14 s long) and one content change at 30-90 s to a lighter (x0.25-0.6) or heavier (x2-3)
content, 500 J/K before. Each runs 180 s on the simulated clock through rasm's runtime under
three conditions:

* ``no twin``: the Hotbox as shipped;
* ``twin (absolute)``: the runtime's twin (``components={"twin": HotboxTwin()}``): Legitimate
  rejects a plan whose 20 s prediction breaks a property;
* ``twin (vs doing nothing)``: the same twin, fed from the runtime's records by this script,
  and a Legitimate stage that rejects a plan only when the twin predicts it breaks a property
  that keeping the current settings would not break, or breaks it earlier
  (``rasm.twin.worse_than_baseline``).

and, to see the twin as a safety net, the last two again with a careless Analyse stage that
ends boost as soon as the box is warm again, lid open or not:

* ``careless analyse, no twin``;
* ``careless analyse, twin (vs doing nothing)``.

Reported per condition: time out of the band (34.5-41 degC, s), executed adaptations,
rejected plans; for the twins: drift alarms, the delay from the content change to the first
alarm, and the published heat capacity's error at the end. The content change is applied by a
subclass of the Hotbox simulator (scenario key ``content_change: [[time, capacity], ...]``).
``--plot`` (default ``docs/images/twin.png``) needs matplotlib (``pip install rasm[docs]``).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import random
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
APP = ROOT / "examples" / "hotbox"
BAND = (34.5, 41.0)
DURATION = 180.0
CONDITIONS = (
    "no twin",
    "twin (absolute)",
    "twin (vs doing nothing)",
    "careless analyse, no twin",
    "careless analyse, twin (vs doing nothing)",
)


def _module(name: str) -> Any:
    qualified = f"rasm_app_hotbox.{name}"  # the runtime's name for it: one copy of the classes
    if qualified not in sys.modules:
        spec = importlib.util.spec_from_file_location(qualified, APP / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[qualified] = module
        spec.loader.exec_module(module)
    return sys.modules[qualified]


def scenario(seed: int) -> dict[str, Any]:
    rng = random.Random(seed)
    openings, t = [], rng.uniform(5.0, 15.0)
    while t < DURATION:
        length = rng.uniform(6.0, 14.0)
        openings.append([round(t, 1), round(length, 1)])
        t += length + rng.uniform(20.0, 40.0)
    factor = rng.uniform(0.25, 0.6) if rng.random() < 0.5 else rng.uniform(2.0, 3.0)
    return {
        "openings": openings,
        "content_heat_capacity": 500.0,
        "content_change": [[round(rng.uniform(30.0, 90.0), 1), round(500.0 * factor, 1)]],
    }


def _simulator_class() -> type:
    components = _module("components")

    class ChangingContent(components.HotboxSimulator):
        """The Hotbox with ``content_change``: from the first step at or after each time the
        content's heat capacity is the new one; the temperature is kept."""

        def __init__(self, scenario: dict | None = None, seed: int = 0) -> None:
            super().__init__(scenario, seed)
            changes = (scenario or {}).get("content_change", [])
            self._changes = sorted((float(t), float(c)) for t, c in changes)

        def step(self, time: float, dt: float) -> dict:
            while self._changes and time >= self._changes[0][0]:
                self.capacity = self._changes.pop(0)[1]  # idempotent if the base does it too
            return super().step(time, dt)

    return ChangingContent


class _VersusDoingNothing:
    """The Hotbox's Legitimate stage plus the twin's comparison with the current settings."""

    def __init__(self, twin: Any, horizon: float, dt: float) -> None:
        from rasm.twin import PredictionChecker

        self.twin, self.horizon, self.dt = twin, horizon, dt
        self.inner = _module("components").HotboxLegitimate()
        self.checker = PredictionChecker(
            [(str(p), p.read_text(encoding="utf-8")) for p in (APP / "properties").glob("*.rv")]
        )

    def legitimate(self, ctx: Any) -> Any:
        from rasm.twin import worse_than_baseline

        verdict = self.inner.legitimate(ctx)
        if verdict is not True:
            return verdict
        worse = worse_than_baseline(
            self.twin,
            self.checker,
            ctx.plan.values,
            ctx.knowledge.snapshot(),
            self.horizon,
            self.dt,
        )
        if worse:
            return False, "; ".join(f"twin:{name}: {why}" for name, why in worse.items())
        return True


class _CarelessAnalyse:
    """The Hotbox's Analyse without its lid check: boost ends once the box is warm again."""

    def analyse(self, ctx: Any) -> Any:
        from rasm.platform.components import Anomaly

        k = ctx.knowledge
        mean = k.read_knowledge("temperature_mean")
        if mean is None:
            return None
        ahead = mean + k.read_knowledge("temperature_trend", 0.0) * 5.0
        mode = k.read_knowledge("heater_mode", "normal")
        if mode == "normal" and (mean < 36.0 or ahead < 35.5):
            return Anomaly("temperature falling out of the band", {"want": "boost"})
        if mode == "boost" and mean >= 37.0:
            return Anomaly("warm again: boost no longer needed", {"want": "normal"})
        return None


def run(seed: int, condition: str) -> dict[str, Any]:
    """One scenario under one condition; the measures."""
    from rasm import Platform, RunOptions
    from rasm.testing.apps import app_manifest

    twin_class = _module("twin").HotboxTwin
    scene = scenario(seed)
    manifest = dataclasses.replace(app_manifest(APP), twin=None)
    twin, components = None, {}
    if condition.startswith("careless"):
        components["analyse"] = _CarelessAnalyse()
    if condition.endswith("twin (absolute)"):
        twin = twin_class()
        components["twin"] = twin
    elif condition.endswith("twin (vs doing nothing)"):
        twin = twin_class()
        components["legitimate"] = _VersusDoingNothing(twin, 20.0, 0.5)
    platform = Platform(
        manifest,
        RunOptions(
            clock="simulated",
            seed=seed,
            knowledge="memory",
            scenario=scene,
            components=components or None,
        ),
    )
    records: list[tuple[float, dict[str, Any]]] = []
    drifts: list[float] = []
    latest: dict[str, Any] = {}

    def observe(time: float, record: dict[str, Any]) -> None:
        records.append((time, dict(record)))
        if record.get("drift") is True:
            drifts.append(time)
        versus = condition.endswith("twin (vs doing nothing)")
        if versus and any(k in record for k in twin.inputs):
            latest.update({k: record[k] for k in twin.inputs if k in record})
            update = twin.observe(time, dict(latest))
            if update is not None and update.drift:
                drifts.append(time)

    platform.on_record.append(observe)
    platform.build()
    platform.assembly.managed_system.simulator = _simulator_class()(scene, seed)
    platform.run(DURATION)
    if condition == "twin (absolute)" and platform.managing.twin is not twin:
        raise SystemExit("this runtime does not take a twin (components={'twin': ...})")
    outside, last = 0.0, None
    for time, record in records:
        if "temperature" in record:
            if last is not None and not (BAND[0] <= last[1] <= BAND[1]):
                outside += time - last[0]
            last = (time, record["temperature"])
    change_at, capacity = scene["content_change"][0]
    out = {
        "seed": seed,
        "condition": condition,
        "outside": outside,
        "executed": sum(1 for _, r in records if r.get("executed") is True),
        "rejected": sum(1 for _, r in records if r.get("rejected") is True),
        "lighter": capacity < 500.0,
    }
    if twin is not None:
        after = [t for t in drifts if t >= change_at]
        out["alarms"] = len(drifts)
        out["false_alarms"] = len(drifts) - len(after)
        out["delay"] = after[0] - change_at if after else None
        # the change shows only when the box moves: time it also from the first lid opening
        # that is under way at or after the change
        moving = [
            max(start, change_at)
            for start, length in scene["openings"]
            if start + length > change_at
        ]
        out["delay_open"] = after[0] - moving[0] if after and moving else None
        learned = twin.model()["params"]["heat_capacity"]
        out["capacity_error"] = abs(learned / capacity - 1.0)
    return out


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def summarise(results: list[dict[str, Any]]) -> list[str]:
    """The markdown table of docs/twin.md."""
    lines = [
        "| condition | time out of band, mean (s) | runs out of band | adaptations, mean "
        "| rejected plans, mean | drift alarms (false) | lighter content: alarm delay after "
        "the change / after the next opening, median (s), detected | heavier content: "
        "detected | capacity error at the end, median |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for condition in CONDITIONS:
        rows = [r for r in results if r["condition"] == condition]
        if not rows:
            continue
        n = len(rows)
        cells = [
            condition,
            f"{statistics.fmean(r['outside'] for r in rows):.1f}",
            f"{sum(r['outside'] > 0 for r in rows)}/{n}",
            f"{statistics.fmean(r['executed'] for r in rows):.1f}",
            f"{statistics.fmean(r['rejected'] for r in rows):.1f}",
        ]
        if "alarms" in rows[0]:
            light = [r for r in rows if r["lighter"]]
            heavy = [r for r in rows if not r["lighter"]]
            delays = [r["delay"] for r in light if r["delay"] is not None]
            opened = [r["delay_open"] for r in light if r["delay_open"] is not None]
            cells += [
                f"{sum(r['alarms'] for r in rows)} ({sum(r['false_alarms'] for r in rows)})",
                f"{_median(delays):.1f} / {_median(opened):.1f}, {len(delays)}/{len(light)}",
                f"{sum(r['delay'] is not None for r in heavy)}/{len(heavy)}",
                f"{100 * _median([r['capacity_error'] for r in rows]):.0f} %",
            ]
        else:
            cells += ["—", "—", "—", "—"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def plot(results: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seeds = sorted({r["seed"] for r in results})
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.5), width_ratios=[2, 1])
    width = 0.8 / len(CONDITIONS)
    for k, condition in enumerate(CONDITIONS):
        by_seed = {r["seed"]: r for r in results if r["condition"] == condition}
        left.bar(
            [i + (k - (len(CONDITIONS) - 1) / 2) * width for i in range(len(seeds))],
            [by_seed[s]["outside"] for s in seeds],
            width,
            label=condition,
        )
    left.set_xticks(range(len(seeds)), [str(s) for s in seeds], fontsize=7)
    left.set_xlabel("scenario (seed)")
    left.set_ylabel("time out of the band (s)")
    left.legend(fontsize=7)
    left.set_title("time out of band per scenario")
    twin_rows = [r for r in results if r["condition"] == "twin (vs doing nothing)"]
    light = [r["delay"] for r in twin_rows if r["lighter"] and r["delay"] is not None]
    heavy = [r["delay"] for r in twin_rows if not r["lighter"] and r["delay"] is not None]
    right.hist([light, heavy], bins=12, label=["lighter content", "heavier content"])
    right.set_xlabel("content change -> drift alarm (s)")
    right.set_ylabel("scenarios")
    right.legend(fontsize=8)
    right.set_title("drift detection delay")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def _one(args: tuple[int, str]) -> dict[str, Any]:
    return run(*args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--plot", default=str(ROOT / "docs" / "images" / "twin.png"))
    args = parser.parse_args(argv)
    jobs = [(seed, condition) for seed in range(1, args.seeds + 1) for condition in CONDITIONS]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(_one, jobs))
    print("\n".join(summarise(results)))
    if args.plot:
        plot(results, Path(args.plot))
        print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
