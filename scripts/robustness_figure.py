"""Draw docs/images/robustness.png: the Hotbox's temperature_band robustness over a run.

Two seeded 70 s runs on the simulated clock: the Hotbox as shipped (its Analyse boosts the
heater when the band's robustness, now or 5 s ahead, falls below 1.5 °C) and the same box
without the loop (no plan). The robustness is read from each run's trace, where the
Trustworthiness Checker writes it as ``robustness_temperature_band``.

    python scripts/robustness_figure.py [OUT.png]     # needs matplotlib (pip install rasm[docs])
"""

from __future__ import annotations

import sys
from pathlib import Path

from rasm import Platform, RunOptions, load_manifest

ROOT = Path(__file__).resolve().parents[1]
HOTBOX = ROOT / "examples" / "hotbox"
KEY = "robustness_temperature_band"


class NoPlan:
    """The loop finds anomalies but never adapts."""

    def plan(self, ctx):
        return None


def run(components: dict | None) -> list[tuple[float, dict]]:
    platform = Platform(load_manifest(HOTBOX), RunOptions(
        clock="simulated", seed=7, knowledge="memory", components=components))
    records: list[tuple[float, dict]] = []
    platform.on_record.append(lambda time, record: records.append((time, dict(record))))
    platform.run(70)
    return records


def series(records: list[tuple[float, dict]]) -> tuple[list[float], list[float]]:
    points = [(t, r[KEY]) for t, r in records if KEY in r]
    return [t for t, _ in points], [v for _, v in points]


def main(out: str = str(ROOT / "docs" / "images" / "robustness.png")) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    adapted, unadapted = run(None), run({"plan": NoPlan()})
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.step(*series(unadapted), where="post", color="#bab0ac", label="without the loop")
    ax.step(*series(adapted), where="post", color="#4c78a8", label="the Hotbox (margin 1.5 °C)")
    ax.axhline(0.0, color="#e15759", linestyle="--", linewidth=1)
    ax.axhline(1.5, color="#f58518", linestyle=":", linewidth=1)
    ax.text(0.5, 0.08, "violated below 0", color="#e15759", fontsize=8)
    ax.text(0.5, 1.58, "margin", color="#f58518", fontsize=8)
    for t, r in adapted:
        if r.get("anomaly"):
            ax.axvline(t, color="#54a24b", linewidth=0.8, alpha=0.6)
    ax.plot([], [], color="#54a24b", linewidth=0.8, label="the Hotbox's anomalies")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("robustness of temperature_band (°C)")
    ax.set_xlim(0, 70)
    ax.set_ylim(-0.3, 3.3)
    fig.legend(loc="upper center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
