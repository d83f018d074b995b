"""Draw docs/images/clearance.png: the TurtleBot's keeps_clearance robustness over a run.

Two seeded runs of generated scenario 1 on the simulated clock, 25 s each: the robot looking for
clearance only once keeps_clearance is violated (boolean), and as shipped (its Analyse chart looks
when the robustness, now or 0.5 s ahead, falls below 0.3 m). The robustness is read from each
run's records, where the Trustworthiness Checker writes it as ``robustness_keeps_clearance``
(+inf while the robot does not drive on: not drawn).

    python scripts/clearance_figure.py [OUT.png]     # needs matplotlib (pip install rasm[docs])
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples" / "turtlebot"))

from tb4.evaluation import APP, LOOK_REASON, analyse_stage  # noqa: E402
from tb4.world import generate_scenario  # noqa: E402

from rasm import Platform, RunOptions, load_manifest  # noqa: E402

KEY = "robustness_keeps_clearance"
SEED, SECONDS = 1, 25.0


def run(look: str) -> list[tuple[float, dict]]:
    platform = Platform(load_manifest(APP), RunOptions(
        clock="simulated", seed=SEED, knowledge="memory", scenario=generate_scenario(SEED),
        components={"analyse": analyse_stage(look)}))
    records: list[tuple[float, dict]] = []
    platform.on_record.append(lambda time, record: records.append((time, dict(record))))
    platform.run(SECONDS)
    return records


def series(records: list[tuple[float, dict]]) -> tuple[list[float], list[float]]:
    points = [(t, r[KEY] if math.isfinite(r[KEY]) else math.nan) for t, r in records if KEY in r]
    return [t for t, _ in points], [v for _, v in points]


def main(out: str = str(ROOT / "docs" / "images" / "clearance.png")) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = {"boolean": run("boolean"), "predictive": run("predictive")}
    fig, ax = plt.subplots(figsize=(9, 3.6))
    styles = {"boolean": ("#bab0ac", "looks once keeps_clearance is violated"),
              "predictive": ("#4c78a8", "as shipped (margin 0.3 m, 0.5 s ahead)")}
    for look, records in runs.items():
        colour, label = styles[look]
        ax.step(*series(records), where="post", color=colour, label=label)
        for t, r in records:
            if r.get("anomaly") and LOOK_REASON in str(r.get("explanation", "")):
                ax.axvline(t, color=colour, linestyle="--", linewidth=1)
    ax.axhline(0.0, color="#e15759", linestyle="--", linewidth=1)
    ax.axhline(0.3, color="#f58518", linestyle=":", linewidth=1)
    ax.text(0.3, 0.03, "violated below 0", color="#e15759", fontsize=8)
    ax.text(0.3, 0.33, "margin", color="#f58518", fontsize=8)
    ax.set_xlabel("time (s); dashed: the looks for clearance")
    ax.set_ylabel("robustness of keeps_clearance (m)")
    ax.set_xlim(0, SECONDS)
    ax.set_ylim(-0.35, 1.05)
    fig.legend(loc="upper center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
