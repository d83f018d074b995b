"""The report's model: stages grouped into iterations, adaptations followed plan by plan."""

from __future__ import annotations

from rasm.report.model import TraceModel, percentiles


def _model(records: list[dict]) -> TraceModel:
    model = TraceModel()
    for record in records:
        record = dict(record)
        model.add(record.pop("time"), record)
    return model


def test_stages_group_into_iterations() -> None:
    model = _model(
        [
            {"time": 0.5, "stage": "monitor", "duration": 0.001},
            {"time": 0.5, "stage": "analyse", "duration": 0.002},
            {"time": 1.0, "stage": "monitor", "duration": 0.003},
            {"time": 1.0, "stage": "analyse", "duration": 0.001},
            {"time": 1.0, "stage": "plan", "duration": 0.004},
            {"time": 1.5, "stage": "analyse", "duration": 0.001},  # its monitor was cut off
        ]
    )
    data = model.to_dict()
    assert [it["time"] for it in data["iterations"]] == [0.5, 1.0, 1.5]
    assert data["iterations"][1]["stages"] == {"monitor": 0.003, "analyse": 0.001, "plan": 0.004}
    assert data["timing"]["analyse"]["count"] == 3


def test_percentiles_are_the_platforms_nearest_rank() -> None:
    values = [i / 100 for i in range(1, 101)]
    got = percentiles(values)
    assert (got["p50"], got["p90"], got["p99"], got["max"]) == (0.5, 0.9, 0.99, 1.0)
    assert percentiles([]) == {}


def test_a_rejected_plan_then_a_replan_then_execution() -> None:
    model = _model(
        [
            {"time": 1, "anomaly": True, "explanation": "too cold"},
            {"time": 1, "planned": True, "plan": "p1", "power": 300, "explanation": "heat hard"},
            {
                "time": 1,
                "rejected": True,
                "plan": "p1",
                "broken_rules": ["power_limit"],
                "explanation": "power 300 > 200",
            },
            {"time": 1.5, "planned": True, "plan": "p2", "power": 150},
            {"time": 1.5, "legitimate": True, "plan": "p2"},
            {"time": 1.5, "trusted": True, "plan": "p2"},
            {"time": 1.5, "executed": True, "plan": "p2", "explanation": "sent"},
        ]
    )
    first, second = model.to_dict()["adaptations"]
    assert (first["plan"], first["legitimacy"], first["outcome"]) == ("p1", "rejected", "rejected")
    assert first["broken_rules"] == ["power_limit"] and first["params"] == {"power": 300}
    assert first["legitimacy_explanation"] == "power 300 > 200"
    assert (second["plan"], second["outcome"], second["trusted"]) == ("p2", "executed", True)
    assert second["anomaly"] == "too cold"  # a replan answers the same anomaly
    assert model.counts() == {
        "anomalies": 1,
        "plans": 2,
        "executed": 1,
        "rejected": 1,
        "dropped": 0,
        "cancelled": 0,
        "fallback": 0,
    }
    assert "power" not in model.signals  # plan parameters are not knowledge


def test_dropped_cancelled_and_unplanned_adaptations() -> None:
    model = _model(
        [
            {"time": 1, "anomaly": True, "explanation": "a"},
            {"time": 1, "explanation": "no plan for the anomaly"},
            {"time": 2, "anomaly": True, "explanation": "b"},
            {"time": 2, "planned": True, "plan": "p1"},
            {"time": 2, "legitimate": True, "plan": "p1"},
            {"time": 2, "dropped": True, "plan": "p1", "explanation": "checker refused"},
            {"time": 3, "anomaly": True, "explanation": "c"},
            {"time": 3, "planned": True, "plan": "p2"},
            {"time": 3, "rejected": True, "plan": "p2", "broken_rules": ["r"]},
            {"time": 3, "explanation": "adaptation cancelled after 2 rejected replans"},
            {"time": 4, "temperature": 20.5, "door": True, "mode": "idle"},
        ]
    )
    outcomes = [(a.plan, a.outcome) for a in model.adaptations]
    assert outcomes == [(None, "no plan"), ("p1", "dropped"), ("p2", "cancelled")]
    assert model.adaptations[1].notes == ["checker refused"]
    assert model.adaptations[2].legitimacy == "rejected"
    assert model.counts()["rejected"] == 1 and model.counts()["cancelled"] == 1
    kinds = {name: s["kind"] for name, s in model.signals.items()}
    assert kinds == {"temperature": "number", "door": "bool", "mode": "str"}


def test_live_history_is_bounded() -> None:
    model = TraceModel(max_points=10)
    for i in range(100):
        model.add(i, {"stage": "monitor", "duration": 0.001, "x": i})
    assert len(model.iterations) == 10 and len(model.signals["x"]["t"]) == 10
    assert model.signals["x"]["v"][-1] == 99


def test_mode_changes_are_rows_and_their_state_keys_no_signals() -> None:
    model = _model(
        [
            {"time": 0.0, "mode": "scanning", "mode_scanning": True},
            {"time": 2.3, "motor_rpm": 600.0, "mode": "stale", "mode_stale": True,
             "mode_scanning": False},
            {"time": 2.6, "ranges": 360, "mode": "scanning", "mode_scanning": True,
             "mode_stale": False},
            {"time": 3.0, "mode_of_transport": "bus"},  # a signal that only looks like one
        ]
    )
    data = model.to_dict()
    assert data["mode_changes"] == [
        {"time": 0.0, "mode": "scanning"},
        {"time": 2.3, "mode": "stale"},
        {"time": 2.6, "mode": "scanning"},
    ]
    assert data["signals"]["mode"]["v"] == ["scanning", "stale", "scanning"]
    assert {"motor_rpm", "ranges", "mode_of_transport"} <= set(data["signals"])
    assert not {"mode_scanning", "mode_stale"} & set(data["signals"])


def test_a_fallback_episode_is_no_adaptation_and_says_why_and_how_long() -> None:
    # the records FallbackSwitch writes: the engagement with its reason, the fallback plan's
    # action (no "planned" record: no anomaly led to it), a retry, the hand-back
    model = _model(
        [
            {"time": 1, "anomaly": True, "explanation": "too cold"},
            {"time": 1, "planned": True, "plan": "p1", "power": 150},
            {"time": 1, "legitimate": True, "plan": "p1"},
            {"time": 2, "fallback": "engaged",
             "explanation": "fallback engaged: veto property band violated at t=2"},
            {"time": 2, "trusted": True, "plan": "f1"},
            {"time": 2, "dropped": True, "plan": "f1", "explanation": "effector unreachable"},
            {"time": 2, "dropped": True, "plan": "p1",
             "explanation": "the fallback holds the effectors"},
            {"time": 2.5, "executed": True, "plan": "f1", "explanation": "sent to heater"},
            {"time": 9, "fallback": "released",
             "explanation": "control handed back: no trigger for 5.0 s"},
            {"time": 12, "fallback": "engaged", "explanation": "fallback engaged: managed "
             "system lost"},
            {"time": 12, "executed": True, "plan": "f2", "explanation": "sent to heater"},
        ]
    )
    data = model.to_dict()
    assert [a["plan"] for a in data["adaptations"]] == ["p1"]  # the fallback's are no rows
    assert data["adaptations"][0]["outcome"] == "dropped"
    first, second = data["fallback"]
    assert first == {
        "engaged": 2, "reason": "veto property band violated at t=2", "released": 9,
        "release": "control handed back: no trigger for 5.0 s", "plan": "f1",
        "actions": [
            {"time": 2, "outcome": "dropped", "explanation": "effector unreachable"},
            {"time": 2.5, "outcome": "executed", "explanation": "sent to heater"},
        ],
    }
    assert (second["reason"], second["released"], second["plan"]) == (
        "managed system lost", None, "f2")
    assert model.counts()["fallback"] == 2 and model.counts()["executed"] == 0


def test_robustness_is_its_own_series_with_infinities_as_text() -> None:
    model = _model([
        {"time": 0.0, "temperature": 37.0},
        {"time": 0.1, "robustness_band": 2.5, "robustness_order": float("inf")},
        {"time": 0.2, "robustness_band": 2.25, "robustness_order": float("-inf")},
    ])
    data = model.to_dict()
    assert data["robustness"] == {
        "band": {"t": [0.1, 0.2], "v": [2.5, 2.25]},
        "order": {"t": [0.1, 0.2], "v": ["inf", "-inf"]},
    }
    assert set(data["signals"]) == {"temperature"}
