"""The data behind the report and the dashboard, built record by record from a trace.

:class:`TraceModel` is fed ``(time, record)`` pairs, in trace order, either from a trace file
(``rasm report``) or from a running platform's ``on_record`` (``rasm run --dashboard``), and
turns them into plain JSON-able data that ``assets/report.js`` draws:

- the MAPLE-K loop iterations: for each, its start time and each stage's duration (Gantt);
- each stage's duration distribution with the platform's nearest-rank percentiles;
- the knowledge signals (every key that is not one of the loop's own keys);
- each property's robustness (``robustness_<property>``, SPEC §12), drawn beside its verdicts
  rather than as a signal; ±inf is the text ``"inf"``/``"-inf"`` (JSON has no infinity);
- the adaptations: anomaly, plan, legitimacy verdict with broken rules, trust check, outcome
  (executed, dropped, cancelled, no plan) and the explanations given on the way;
- the managed system's mode changes, when the app has a modes chart (``mode`` records; their
  ``mode_<state>`` keys are not drawn as signals of their own);
- the fallback episodes: when the fallback engaged and why, its actions (sent or dropped, each
  with its explanation), when control was handed back (``fallback`` records, and the records of
  the plan that is no adaptation's: it has no ``planned`` record, and comes while the fallback
  holds).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

from rasm.loop import EVENTS, LOOP_KEYS, ROBUSTNESS_PREFIX, STAGES

__all__ = ["Adaptation", "TraceModel", "percentiles"]


def percentiles(values: Iterable[float], qs: tuple[float, ...] = (50, 90, 99)) -> dict[str, float]:
    """Nearest-rank percentiles, as ``rasm run`` prints them (``{"p50": …, "p90": …}``)."""
    ordered = sorted(values)
    if not ordered:
        return {}
    out = {}
    for q in qs:
        k = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
        out[f"p{q:g}"] = ordered[k]
    out["max"] = ordered[-1]
    out["mean"] = sum(ordered) / len(ordered)
    out["count"] = len(ordered)
    return out


@dataclass
class Adaptation:
    """One plan's way through the loop (or an anomaly that never got a plan)."""

    number: int
    time: float
    anomaly: str | None = None
    anomaly_time: float | None = None
    plan: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    plan_explanation: str | None = None
    legitimacy: str | None = None  # accepted | rejected
    broken_rules: list[str] = field(default_factory=list)
    legitimacy_explanation: str | None = None
    trusted: bool | None = None
    outcome: str | None = None  # executed | dropped | cancelled | no plan | stage failed
    outcome_time: float | None = None
    notes: list[str] = field(default_factory=list)


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class TraceModel:
    """Everything the views draw, kept up to date one record at a time.

    ``max_points`` bounds each signal's and each stage's history (the dashboard of a long run
    keeps the most recent ones); ``None`` keeps everything (the offline report).
    """

    def __init__(self, *, max_points: int | None = None) -> None:
        self.max_points = max_points
        self.records = 0
        self.first_time: float | None = None
        self.last_time: float | None = None
        self.iterations: list[dict[str, Any]] = []  # {"time": t, "stages": {stage: seconds}}
        self.durations: dict[str, list[float]] = {s: [] for s in STAGES}
        self.other_stages: set[str] = set()
        self.signals: dict[str, dict[str, Any]] = {}
        # property -> its robustness over time (robustness_<property> in the records)
        self.robustness: dict[str, dict[str, list]] = {}
        self.adaptations: list[Adaptation] = []
        self.mode_changes: list[dict[str, Any]] = []  # {"time": t, "mode": active modes}
        self._open: Adaptation | None = None  # the adaptation the loop is working on
        self._anomaly: tuple[float, str | None] | None = None
        self._by_plan: dict[str, Adaptation] = {}
        self.anomalies = 0
        self.fallback: list[dict[str, Any]] = []  # the fallback's episodes, in order
        self._fallback_plans: dict[str, dict[str, Any]] = {}  # plan id -> its episode

    # ------------------------------------------------------------------ feeding

    def add(self, time: float, record: dict[str, Any]) -> None:
        """Take one trace record (``time`` apart from the other keys)."""
        self.records += 1
        if self.first_time is None:
            self.first_time = time
        self.last_time = time
        if "stage" in record:
            self._stage(time, record)
        if record.get("fallback") in ("engaged", "released"):
            self._fallback(time, record)
        if self._fallback_action(time, record):
            pass
        elif any(record.get(event) is True for event in EVENTS) or "plan" in record:
            self._event(time, record)
        elif "explanation" in record and "stage" not in record:
            self._note(time, str(record["explanation"]))
        if record.get("planned") is True:
            return  # the other keys of a plan record are the plan's parameters, not knowledge
        changed = isinstance(record.get("mode"), str) and any(k.startswith("mode_") for k in record)
        if changed:  # the modes chart's change: one row, not a signal per state
            self.mode_changes.append({"time": time, "mode": record["mode"]})
            self._trim(self.mode_changes)
        for key, value in record.items():
            if key.startswith(ROBUSTNESS_PREFIX):
                self._robustness(time, key.removeprefix(ROBUSTNESS_PREFIX), value)
            elif key not in LOOP_KEYS and not (changed and key.startswith("mode_")):
                self._signal(time, key, value)

    def _fallback(self, time: float, record: dict[str, Any]) -> None:
        text = str(record.get("explanation") or "")
        if record["fallback"] == "engaged":
            self.fallback.append({
                "engaged": time, "reason": text.removeprefix("fallback engaged: ") or None,
                "released": None, "release": None, "plan": None, "actions": [],
            })
            self._trim(self.fallback)
        elif self.fallback and self.fallback[-1]["released"] is None:
            self.fallback[-1]["released"] = time
            self.fallback[-1]["release"] = text or None

    def _fallback_action(self, time: float, record: dict[str, Any]) -> bool:
        """A record about the fallback's plan: counted in its episode, not as an adaptation."""
        plan = record.get("plan")
        if plan is None or record.get("planned") is True:
            return False
        plan = str(plan)
        episode = self._fallback_plans.get(plan)
        if episode is None:
            engaged = self.fallback[-1] if self.fallback else None
            if (engaged is None or engaged["released"] is not None or plan in self._by_plan
                    or engaged["plan"] is not None):
                return False
            episode = self._fallback_plans[plan] = engaged  # the plan the engagement sent
            engaged["plan"] = plan
        for outcome in ("executed", "dropped"):
            if record.get(outcome) is True:
                explanation = record.get("explanation")
                episode["actions"].append({
                    "time": time, "outcome": outcome,
                    "explanation": str(explanation) if explanation is not None else None,
                })
        return True

    def _stage(self, time: float, record: dict[str, Any]) -> None:
        stage = str(record["stage"])
        duration = record.get("duration")
        seconds = float(duration) if isinstance(duration, int | float) else None
        if stage not in STAGES:
            self.other_stages.add(stage)
            return
        current = self.iterations[-1] if self.iterations else None
        order = STAGES.index(stage)
        if (
            current is None
            or stage == "monitor"
            or any(STAGES.index(s) >= order for s in current["stages"])
        ):
            current = {"time": time, "stages": {}}
            self.iterations.append(current)
            self._trim(self.iterations)
        current["stages"][stage] = seconds
        if seconds is not None:
            self.durations[stage].append(seconds)
            self._trim(self.durations[stage])

    def _signal(self, time: float, key: str, value: Any) -> None:
        value = _finite(value)
        if isinstance(value, bool):
            kind = "bool"
        elif isinstance(value, int | float):
            kind = "number"
        elif isinstance(value, str):
            kind = "str"
        else:
            return  # lists and objects are not drawn
        series = self.signals.get(key)
        if series is None:
            series = self.signals[key] = {"kind": kind, "t": [], "v": []}
        elif series["kind"] != kind:
            if {series["kind"], kind} == {"number", "bool"}:
                series["kind"] = "number"
            else:
                series["kind"] = "str"
        series["t"].append(time)
        series["v"].append(value)
        if self.max_points is not None and len(series["t"]) > self.max_points:
            del series["t"][0], series["v"][0]

    def _robustness(self, time: float, name: str, value: Any) -> None:
        """A property's robustness, drawn beside its verdicts: JSON has no infinity, so ±inf
        (decided by booleans alone) is kept as the text "inf" or "-inf"."""
        if isinstance(value, bool) or not isinstance(value, int | float) or value != value:
            return
        if math.isinf(value):
            value = "inf" if value > 0 else "-inf"
        series = self.robustness.setdefault(name, {"t": [], "v": []})
        series["t"].append(time)
        series["v"].append(value)
        if self.max_points is not None and len(series["t"]) > self.max_points:
            del series["t"][0], series["v"][0]

    def _trim(self, items: list) -> None:
        if self.max_points is not None and len(items) > self.max_points:
            del items[0]

    # ------------------------------------------------------------------ adaptations

    def _new(self, time: float) -> Adaptation:
        adaptation = Adaptation(number=len(self.adaptations) + 1, time=time)
        self.adaptations.append(adaptation)
        self._open = adaptation
        return adaptation

    def _event(self, time: float, record: dict[str, Any]) -> None:
        explanation = record.get("explanation")
        text = str(explanation) if explanation is not None else None
        if record.get("anomaly") is True:
            self.anomalies += 1
            if self._open is not None and self._open.plan is None and self._open.outcome is None:
                self._open.outcome = "no plan"  # the previous anomaly was never planned for
            self._anomaly = (time, text)
            adaptation = self._new(time)
            adaptation.anomaly, adaptation.anomaly_time = text or "anomaly", time
            return
        plan = record.get("plan")
        plan = str(plan) if plan is not None else None
        adaptation = self._by_plan.get(plan) if plan is not None else self._open
        if record.get("planned") is True or adaptation is None:
            adaptation = self._planned(time, plan, record, text)
        if record.get("legitimate") is True:
            adaptation.legitimacy = "accepted"
        if record.get("rejected") is True:
            adaptation.legitimacy = "rejected"
            rules = record.get("broken_rules") or []
            adaptation.broken_rules = [str(r) for r in rules] if isinstance(rules, list) else [
                str(rules)
            ]
            adaptation.legitimacy_explanation = text
            adaptation.outcome, adaptation.outcome_time = "rejected", time
        if record.get("trusted") is True:
            adaptation.trusted = True
        for outcome in ("executed", "dropped"):
            if record.get(outcome) is True:
                if adaptation.outcome != "executed":
                    adaptation.outcome, adaptation.outcome_time = outcome, time
                if text:
                    adaptation.notes.append(text)

    def _planned(
        self, time: float, plan: str | None, record: dict[str, Any], text: str | None
    ) -> Adaptation:
        current = self._open
        if current is not None and current.plan is None and current.outcome in (None, "no plan"):
            adaptation = current  # the anomaly's first plan
            adaptation.outcome = None
        else:
            adaptation = self._new(time)
            if self._anomaly is not None and current is not None and current.outcome == "rejected":
                # a replan: same anomaly, next plan
                adaptation.anomaly_time, adaptation.anomaly = self._anomaly
        adaptation.plan = plan
        adaptation.time = adaptation.anomaly_time if adaptation.anomaly_time is not None else time
        if record.get("planned") is True:
            adaptation.params = {
                k: _finite(v) for k, v in record.items() if k not in LOOP_KEYS and k != "time"
            }
            adaptation.plan_explanation = text
        if plan is not None:
            self._by_plan[plan] = adaptation
        self._open = adaptation
        return adaptation

    def _note(self, time: float, text: str) -> None:
        adaptation = self._open
        if adaptation is None or adaptation.outcome in ("executed", "dropped"):
            return
        adaptation.notes.append(text)
        if text.startswith("adaptation cancelled"):
            adaptation.outcome, adaptation.outcome_time = "cancelled", time
        elif text == "no plan for the anomaly":
            adaptation.outcome, adaptation.outcome_time = "no plan", time
        elif " stage failed" in text or "overran" in text:
            if adaptation.outcome is None:
                adaptation.outcome, adaptation.outcome_time = "stage failed", time

    # ------------------------------------------------------------------ output

    def counts(self) -> dict[str, int]:
        """Anomalies, plans, plans executed, rejected (by Legitimate), dropped, cancelled, and
        how often the fallback engaged (its actions are no adaptation's)."""
        out = {"anomalies": self.anomalies}
        out["plans"] = sum(1 for a in self.adaptations if a.plan is not None)
        out["executed"] = sum(1 for a in self.adaptations if a.outcome == "executed")
        out["rejected"] = sum(1 for a in self.adaptations if a.legitimacy == "rejected")
        for outcome in ("dropped", "cancelled"):
            out[outcome] = sum(1 for a in self.adaptations if a.outcome == outcome)
        out["fallback"] = len(self.fallback)
        return out

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able data the page draws: a copy, safe to serialise while records arrive."""
        return {
            "records": self.records,
            "start": self.first_time,
            "end": self.last_time,
            "stages": list(STAGES),
            "other_stages": sorted(self.other_stages),
            "iterations": [
                {"time": it["time"], "stages": dict(it["stages"])} for it in self.iterations
            ],
            "timing": {
                stage: percentiles(values) for stage, values in self.durations.items() if values
            },
            "durations": {
                stage: list(values) for stage, values in self.durations.items() if values
            },
            "signals": {
                name: {"kind": s["kind"], "t": list(s["t"]), "v": list(s["v"])}
                for name, s in self.signals.items()
            },
            "robustness": {
                name: {"t": list(r["t"]), "v": list(r["v"])} for name, r in self.robustness.items()
            },
            "adaptations": [asdict(a) for a in self.adaptations],
            "mode_changes": [dict(change) for change in self.mode_changes],
            "fallback": [
                {**episode, "actions": [dict(a) for a in episode["actions"]]}
                for episode in self.fallback
            ],
            "counts": self.counts(),
        }
