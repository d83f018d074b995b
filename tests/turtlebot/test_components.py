"""The MAPLE-K components on hand-made knowledge: when Analyse raises, what Plan makes of it."""

from __future__ import annotations

import pytest
from tb4.evaluation import APP

from rasm.knowledge import KnowledgeBase
from rasm.platform.components import StageContext
from rasm.platform.loading import load_component

FRONT = [None if i < 61 or i >= 300 else 3.0 for i in range(360)]  # 121 rays blocked ahead
CLEAR = [3.0] * 360


def component(name):
    return load_component(f"components:{name}", APP, package="rasm_app_turtlebot")


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
    ctx = StageContext(kb, 2.0, 1)
    anomaly = component("OcclusionAnalyse").analyse(ctx)
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
    assert (
        component("OcclusionAnalyse").analyse(StageContext(knowledge(FRONT, 66.0), 2.0, 1)) is None
    )
    assert (
        component("OcclusionAnalyse").analyse(StageContext(knowledge(FRONT, 65.0), 2.0, 1))
        is not None
    )


def test_a_clear_lidar_with_a_plan_in_force_asks_to_stop_spinning():
    kb = knowledge(CLEAR, spin_rotation=66.0)
    ctx = StageContext(kb, 2.0, 1)
    anomaly = component("OcclusionAnalyse").analyse(ctx)
    assert anomaly is not None and "clear again" in anomaly.reason
    ctx.anomaly = anomaly
    assert component("SpinPlan").plan(ctx)["rotation"] == 0.0
    assert component("OcclusionAnalyse").analyse(StageContext(knowledge(CLEAR), 2.0, 1)) is None


def test_analyse_waits_for_a_full_window_and_settles_after_raising():
    assert (
        component("OcclusionAnalyse").analyse(StageContext(knowledge(FRONT, scans=9), 2.0, 1))
        is None
    )
    analyse = component("OcclusionAnalyse")
    kb = knowledge(FRONT)
    assert analyse.analyse(StageContext(kb, 2.0, 1)) is not None
    assert analyse.analyse(StageContext(kb, 2.8, 2)) is None  # waiting for the robot's echo
    assert analyse.analyse(StageContext(kb, 3.0, 3)) is not None


def test_after_a_rejection_the_plan_turns_more_gently():
    ctx = StageContext(knowledge(FRONT), 2.0, 1)
    ctx.anomaly = component("OcclusionAnalyse").analyse(ctx)
    first = component("SpinPlan").plan(ctx)
    ctx.rejections = [(first, ["application"], "too fast")]
    second = component("SpinPlan").plan(ctx)
    assert second["angular_velocity"] == pytest.approx(0.75 * first["angular_velocity"])
    assert second["spin_duration"] > first["spin_duration"]
