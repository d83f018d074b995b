"""legitimate.repair: nearest, end to end: a plan the rules reject is followed by the nearest
legitimate plan (``repaired_from`` in the trace), which then passes Legitimate, the trust
check and the checker like any other plan, instead of a cancelled adaptation."""

from __future__ import annotations

import pytest

from rasm import Platform, RunOptions
from rasm.errors import SourceErrors
from rasm.platform.components import Plan
from rasm.testing import run_app

from .guarded import write_guarded_app

RULES = """variables:
  level: {type: int, min: 0, max: 5}
  speed: {type: real, min: 0, max: 10}
rules:
  - name: gentle
    require: level <= 3
"""


def write_app(folder, *, repair="nearest", weights=""):
    app = write_guarded_app(folder, every=4, veto=())
    (app / "rules").mkdir(exist_ok=True)
    (app / "rules" / "robot.yaml").write_text(RULES)
    text = (app / "app.yaml").read_text().replace(
        "plan: components:Level", "plan: {component: components:Level, produces: {level: int}}"
    ).replace("trustworthiness:\n  veto_properties: []\n", "")
    text += f"rules: rules/robot.yaml\nlegitimate:\n  repair: {repair}\n{weights}"
    (app / "app.yaml").write_text(text)
    return app


class Greedy:
    def plan(self, ctx):
        return Plan({"level": 5}, explanation="full speed")


class Fussy:
    """The app's own Legitimate refuses level 3: the repair is rejected too."""

    def legitimate(self, ctx):
        return (False, "not 3") if ctx.plan["level"] == 3 else True


def test_a_rejected_plan_is_followed_by_its_nearest_legitimate_plan(tmp_path):
    trace = run_app(write_app(tmp_path / "app"), seed=1, duration=5,
                    components={"plan": Greedy()})
    planned = [r for r in trace if r.get("planned")]
    assert planned[0]["level"] == 5 and "repaired_from" not in planned[0]
    repaired = planned[1]
    assert repaired["repaired_from"] == planned[0]["plan"] and repaired["level"] == 3
    assert repaired["explanation"] == f"the nearest legitimate plan to {planned[0]['plan']}: " \
                                      "level 5 -> 3"
    executed = {r["plan"] for r in trace if r.get("executed")}
    trusted = {r["plan"] for r in trace if r.get("trusted")}
    assert repaired["plan"] in executed and repaired["plan"] in trusted
    assert planned[0]["plan"] not in executed
    assert trace.summary.stats.cancelled == 0


def test_without_repair_the_same_planner_ends_in_a_cancelled_adaptation(tmp_path):
    trace = run_app(write_app(tmp_path / "app", repair="off"), seed=1, duration=5,
                    components={"plan": Greedy()})
    assert not any("repaired_from" in r for r in trace)
    assert not any(r.get("executed") for r in trace)
    assert trace.summary.stats.cancelled >= 1


def test_a_rejected_repair_goes_back_to_the_planner(tmp_path):
    trace = run_app(write_app(tmp_path / "app"), seed=1, duration=3,
                    components={"plan": Greedy(), "legitimate": Fussy()})
    planned = [r for r in trace if r.get("planned")]
    # p1 (5) rejected by the rules, p2 its repair (3) rejected by the app, p3 the planner's again
    assert [r["level"] for r in planned[:3]] == [5, 3, 5]
    assert "repaired_from" in planned[1] and "repaired_from" not in planned[2]
    assert not any(r.get("executed") for r in trace)


def test_a_weight_for_no_rule_variable_is_refused_at_its_place(tmp_path):
    app = write_app(tmp_path / "app", weights="  weights: {levle: 2}\n")
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated", knowledge="memory")).build()
    assert "app.yaml:" in str(caught.value)
    message = str(caught.value)
    assert "repair weight for 'levle', which is no rule variable (level, speed)" in message
