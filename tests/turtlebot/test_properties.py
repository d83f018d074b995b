"""The application's properties catch what they name, on small hand-made traces."""

from __future__ import annotations

from rasm.properties import compile_properties

from .conftest import APP

PROPERTIES = (APP / "properties" / "turtlebot.rv").read_text()
BASE = {"velocity": 0.2, "yaw_rate": 0.0}


def violated(records):
    """The properties false at some record of ``records`` (``(time, values)`` pairs)."""
    monitor = compile_properties(PROPERTIES, source="turtlebot.rv")
    runs = monitor.run(
        [(t, {**BASE, **r}) if i == 0 else (t, r) for i, (t, r) in enumerate(records)]
    )
    return {run.name for run in runs if any(v is False for v in run.values)}


def iteration(t, *stages, anomaly=False, rejected_after_first_plan=False):
    """Stage records of one loop iteration at time ``t`` with the events the loop writes."""
    out = []
    for stage in stages:
        out.append((t, {"stage": stage, "duration": 0.001}))
        if stage == "analyse" and anomaly:
            out.append((t, {"anomaly": True}))
        if stage == "plan":
            out.append((t, {"planned": True}))
        if stage == "legitimate":
            if rejected_after_first_plan:
                out.append((t, {"rejected": True}))
                rejected_after_first_plan = False
            else:
                out.append((t, {"legitimate": True}))
        if stage == "execute":
            out.append((t, {"executed": True}))
    return out


FULL = ("monitor", "analyse", "plan", "legitimate", "execute")


def test_a_well_ordered_loop_with_a_replan_satisfies_every_property():
    trace = [
        *iteration(0.2, "monitor", "analyse"),
        *iteration(
            0.4,
            "monitor",
            "analyse",
            "plan",
            "legitimate",
            "plan",
            "legitimate",
            "execute",
            anomaly=True,
            rejected_after_first_plan=True,
        ),
        *iteration(0.6, "monitor", "analyse"),
    ]
    assert violated(trace) == set()


def test_skipping_legitimate_breaks_the_stage_order():
    trace = [*iteration(0.2, "monitor", "analyse", "plan", "execute", anomaly=True)]
    assert violated(trace) == {"maple_stage_order"}


def test_analysing_without_monitoring_breaks_the_stage_order():
    trace = [*iteration(0.2, *FULL, anomaly=True), *iteration(0.4, "analyse")]
    assert violated(trace) == {"maple_stage_order"}


def test_an_unanswered_anomaly_breaks_timeliness():
    trace = [*iteration(0.2, "monitor", "analyse", anomaly=True), *iteration(1.4, "monitor")]
    assert violated(trace) == {"timely_spin_plan"}


def test_speeding_spinning_too_fast_and_bumping_are_caught():
    start = iteration(0.2, "monitor")
    assert violated([*start, (0.3, {"velocity": 0.35})]) == {"velocity_limit"}
    assert violated([*start, (0.3, {"yaw_rate": -1.7})]) == {"velocity_limit"}
    assert violated([*start, (0.3, {"collision": True})]) == {"no_collision"}


def test_new_debris_must_be_answered_within_four_seconds():
    start = [*iteration(0.2, "monitor"), (0.3, {"debris": 0})]
    late = [*start, (1.0, {"debris": 1}), *iteration(5.2, *FULL, anomaly=True)]
    timely = [
        *start,
        (1.0, {"debris": 1}),
        *iteration(2.4, *FULL, anomaly=True),
        (6.0, {"debris": 1}),
    ]
    assert violated(late) == {"occlusion_compensated"}
    assert violated(timely) == set()


def test_a_spin_plan_executed_after_arrival_breaks_nothing_after_arrival():
    arrived = [(1.0, {"mode": "arrived", "mode_arrived": True})]
    assert violated([*arrived, *iteration(1.2, *FULL, anomaly=True)]) == {"nothing_after_arrival"}
    assert violated([*iteration(0.8, *FULL, anomaly=True), *arrived]) == set()


def test_driving_on_beyond_what_was_seen_free_breaks_keeps_clearance_once_the_robot_has_looked():
    navigate = {"mode_navigate": True, "mode_spin": False}
    spin = {"mode_navigate": False, "mode_spin": True}
    start = [*iteration(0.2, "monitor"), (0.3, {**navigate, "clearance": 0.0, "velocity": 0.3})]
    # before the first look the robot drives on its own knowledge: not the loop's doing
    assert violated(start) == set()
    looked = [*start, (0.5, spin), (3.5, {**navigate, "clearance": 0.8, "velocity": 0.3})]
    assert violated(looked) == set()
    # braking for a look with little seen free ahead is not driving on
    braking = [*looked, (4.0, {**spin, "clearance": 0.1, "velocity": 0.2})]
    assert violated(braking) == set()
    blind = [*looked, (4.0, {"clearance": 0.25})]  # 0.3 m/s: 0.3 m in the next second
    assert violated(blind) == {"keeps_clearance"}
