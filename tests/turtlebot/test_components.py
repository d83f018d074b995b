"""The MAPLE-K components on hand-made knowledge: what Monitor sees in the scans, when the
Analyse chart raises, what Plan makes of it."""

from __future__ import annotations

import pytest
from tb4.evaluation import APP

from rasm.knowledge import KnowledgeBase
from rasm.platform.chart_stages import ChartStage
from rasm.platform.components import StageContext
from rasm.platform.loading import load_component

FRONT = [None if i < 61 or i >= 300 else 3.0 for i in range(360)]  # 121 rays blocked ahead
CLEAR = [3.0] * 360


def component(name):
    return load_component(f"components:{name}", APP, package="rasm_app_turtlebot")


def analyse_chart():
    return ChartStage(APP / "statecharts" / "analyse.yaml", "analyse")


def monitored(kb, time):
    """The Monitor's signals, stored as the platform stores them; the stage context."""
    ctx = StageContext(kb, time, 1)
    kb.register_values(component("ScanMonitor").monitor(ctx), time)
    return ctx


def knowledge(scan, spin_rotation=0.0, scans=10):
    kb = KnowledgeBase()
    for k in range(scans):
        kb.register_knowledge("ranges", scan, k * 0.2)
        kb.register_knowledge("scan_pose", [1.0, 2.5, 0.0], k * 0.2)
    for key, value in {
        "nav_mode": "navigate",
        "spin_rotation": spin_rotation,
        "x": 1.0,
        "y": 2.5,
        "yaw": 0.0,
        "velocity": 0.3,
    }.items():
        kb.register_knowledge(key, value, 2.0)
    return kb


def test_an_uncovered_occlusion_is_an_anomaly_and_the_plan_covers_it():
    kb = knowledge(FRONT)
    ctx = monitored(kb, 2.0)
    assert kb.read_knowledge("occlusion") == "uncovered"
    anomaly = analyse_chart().analyse(ctx)
    assert anomaly is not None and anomaly.data["windows"] == [[300, 121]]
    assert "121 deg wide at 0 deg" in anomaly.reason
    ctx.anomaly = anomaly
    plan = component("SpinPlan").plan(ctx)
    assert plan["rotation"] == 66.0 and plan["stop_every"] == 4.0
    ctx.plan = plan
    assert component("SpinLegitimate").legitimate(ctx) == (True, "")
    action = component("SpinExecute").execute(ctx)
    assert action.effector == "spin_config"
    assert action.payload == {
        "rotation": 66.0,
        "angular_velocity": 90.0,
        "stop_every": 4.0,
        "spin_duration": 2.934,
    }


def test_an_occlusion_the_plan_in_force_covers_is_no_anomaly():
    covered = knowledge(FRONT, 66.0)
    assert analyse_chart().analyse(monitored(covered, 2.0)) is None
    assert covered.read_knowledge("occlusion") == "covered"
    short = knowledge(FRONT, 65.0)
    assert analyse_chart().analyse(monitored(short, 2.0)) is not None


def test_a_clear_lidar_asks_to_stop_spinning_only_after_staying_clear():
    analyse = analyse_chart()
    kb = knowledge(FRONT)
    assert analyse.analyse(monitored(kb, 2.0)) is not None
    for k in range(10):  # the debris is gone; the robot still sweeps ±66 deg
        kb.register_knowledge("ranges", CLEAR, 2.2 + k * 0.2)
    kb.register_knowledge("spin_rotation", 66.0, 4.0)
    assert analyse.analyse(monitored(kb, 4.0)) is None  # clear: recovering starts
    assert analyse.analyse(monitored(kb, 4.6)) is None  # hysteresis: not clear for 1 s yet
    anomaly = analyse.analyse(monitored(kb, 5.0))
    assert anomaly is not None and "clear again" in anomaly.reason
    ctx = monitored(kb, 5.0)
    ctx.anomaly = anomaly
    assert component("SpinPlan").plan(ctx)["rotation"] == 0.0
    assert "clear" in analyse.interpreter.configuration


def test_analyse_waits_for_a_full_window_and_settles_after_raising():
    assert analyse_chart().analyse(monitored(knowledge(FRONT, scans=9), 2.0)) is None
    analyse = analyse_chart()
    kb = knowledge(FRONT)
    assert analyse.analyse(monitored(kb, 2.0)) is not None
    assert analyse.analyse(monitored(kb, 2.8)) is None  # waiting for the robot's echo
    assert analyse.analyse(monitored(kb, 3.0)) is not None


def test_after_a_rejection_the_plan_turns_more_gently():
    kb = knowledge(FRONT)
    ctx = monitored(kb, 2.0)
    ctx.anomaly = analyse_chart().analyse(ctx)
    first = component("SpinPlan").plan(ctx)
    ctx.rejections = [(first, ["application"], "too fast")]
    second = component("SpinPlan").plan(ctx)
    assert second["angular_velocity"] == pytest.approx(0.75 * first["angular_velocity"])
    assert second["spin_duration"] > first["spin_duration"]


def test_the_monitor_measures_the_clearance_seen_free_ahead():
    """Walls 3 m around, seen by clear scans: the clearance runs to its 1 m horizon; with the debris
    on every scan, nothing ahead was ever seen, so it is 0 and ends in unseen space."""
    clear = monitored(knowledge(CLEAR), 2.0).knowledge
    assert clear.read_knowledge("clearance") == 1.0
    assert clear.read_knowledge("clearance_unseen") is False
    blind = monitored(knowledge(FRONT), 2.0).knowledge
    assert blind.read_knowledge("clearance") == 0.0
    assert blind.read_knowledge("clearance_unseen") is True


def looking(chart, time, robustness, ahead, unseen=True, velocity=0.3):
    """Analyse with a covered occlusion while the robot drives, the clearance as given:
    ``robustness`` of keeps_clearance now, ``ahead`` m seen free from where the robot will be
    in 0.5 s."""
    kb = knowledge(FRONT, 66.0)
    ctx = monitored(kb, time)
    for key, value in {"robustness_keeps_clearance": robustness, "clearance_ahead": ahead,
                       "clearance_unseen": unseen, "velocity": velocity}.items():
        kb.register_knowledge(key, value, time)
    return chart.analyse(ctx)


def occluded_chart(**variables):
    """The Analyse chart after its first anomaly (the plan covering the debris is in force)."""
    chart = analyse_chart()
    chart.interpreter.context.update(variables)
    assert chart.analyse(monitored(knowledge(FRONT), 2.0)) is not None
    return chart


def test_the_robot_looks_when_the_clearance_robustness_now_or_ahead_falls_below_the_margin():
    assert looking(occluded_chart(), 3.2, robustness=0.5, ahead=1.0) is None
    look = looking(occluded_chart(), 3.2, robustness=0.25, ahead=1.0)
    assert look is not None and "seen free ahead" in look.reason
    assert look.data["windows"] == [[300, 121]]  # the plan in force, sent again
    # 0.5 s ahead the robot will see 0.5 m free, 0.2 m beyond its second of driving
    assert looking(occluded_chart(), 3.2, robustness=1.0, ahead=0.5) is not None
    assert looking(occluded_chart(), 3.2, robustness=1.0, ahead=0.7) is None


def test_an_echo_ahead_is_looked_at_only_once_the_robot_would_not_stop_short_of_it():
    # an obstacle the scans have seen ends the clearance: the planner slows down for it...
    assert looking(occluded_chart(), 3.2, robustness=0.1, ahead=0.35, unseen=False) is None
    # ...unless it does not know it (seen from afar, then hidden by the debris): look
    assert looking(occluded_chart(), 3.2, robustness=0.1, ahead=0.25, unseen=False) is not None


def test_no_look_for_a_standing_robot_or_within_the_settle_time():
    assert looking(occluded_chart(), 3.2, robustness=0.1, ahead=0.2, velocity=0.0) is None
    assert looking(occluded_chart(), 2.8, robustness=0.1, ahead=0.2) is None


def test_the_boolean_look_waits_for_the_violation():
    boolean = {"margin": 0.0, "lookahead": False}
    assert looking(occluded_chart(**boolean), 3.2, robustness=0.05, ahead=0.0) is None
    assert looking(occluded_chart(**boolean), 3.2, robustness=-0.05, ahead=0.0) is not None
