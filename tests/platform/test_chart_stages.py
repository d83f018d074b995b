"""A stage written as a chart: what it answers, and how it fails (as a Python stage would)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.knowledge import KnowledgeBase
from rasm.platform.app_charts import stage_chart_problems
from rasm.platform.chart_stages import MAX_STEPS, STAGE_OUTCOMES, ChartStage, NoAnswer
from rasm.platform.components import Action, Anomaly, Plan, StageContext, StageError
from rasm.statechart import load_statechart


def chart(stage: str, action: str, guard: str = "True", preamble: str = "x = 0") -> ChartStage:
    text = f"""statechart:
  name: {stage}_chart
  preamble: |
    {preamble}
  root state:
    name: root
    transitions:
      - event: {stage}
        guard: {guard}
        action: |
          {action}
"""
    return ChartStage(load_statechart(text=text), stage)


def ctx(time: float = 1.0, **knowledge) -> StageContext:
    kb = KnowledgeBase()
    for key, value in knowledge.items():
        kb.register_knowledge(key, value, 0.0)
    return StageContext(kb, time, 1)


def test_each_stage_answers_with_its_outcomes():
    assert chart("monitor", "send('monitored', mean=2.5)").monitor(ctx()) == {"mean": 2.5}
    assert chart("monitor", "send('monitored')").monitor(ctx()) is None
    anomaly = chart("analyse", "send('anomaly', reason='hot', t=knowledge['t'])").analyse(
        ctx(t=41.0)
    )
    assert anomaly == Anomaly("hot", {"t": 41.0})
    assert chart("analyse", "send('no_anomaly')").analyse(ctx()) is None
    plan = chart("plan", "send('planned', setpoint=37.0, explanation='cool')").plan(ctx())
    assert plan == Plan({"setpoint": 37.0}, explanation="cool")
    assert chart("legitimate", "send('accepted')").legitimate(ctx()) is True
    assert chart("legitimate", "send('rejected', reason='too hot')").legitimate(ctx()) == (
        False, "too hot")
    two = "send('action', effector='a', payload={'v': 1}); send('action', effector='b')"
    assert chart("execute", two).execute(ctx()) == [Action("a", {"v": 1}), Action("b", {})]
    assert chart("execute", "send('no_action')").execute(ctx()) == []


def test_the_context_is_the_iteration_and_the_knowledge_read_only():
    stage = chart("plan", "send('planned', seen=[time, iteration, anomaly, rejections])")
    c = ctx(3.5)
    c.anomaly = Anomaly("cold", {"by": 2})
    assert stage.plan(c)["seen"] == [3.5, 1, {"by": 2, "reason": "cold"}, 0]
    kb_stage = chart("monitor", "knowledge['xs'].append(4); send('monitored')")
    c = ctx(xs=[1, 2])
    kb_stage.monitor(c)
    assert c.knowledge.read_knowledge("xs") == [1, 2]  # the chart changed a copy


def test_a_chart_without_an_answer_raises_no_answer():
    with pytest.raises(NoAnswer, match="sent no outcome"):
        chart("analyse", "x += 1").analyse(ctx())
    with pytest.raises(NoAnswer):
        chart("analyse", "send('no_anomaly')", guard="False").analyse(ctx())


def test_two_answers_a_failing_step_and_a_chart_that_never_settles_fail_the_stage():
    with pytest.raises(StageError, match="answered twice"):
        chart("analyse", "send('anomaly'); send('no_anomaly')").analyse(ctx())
    failing = chart("analyse", "x = 1 / 0")
    with pytest.raises(StageError, match="division by zero"):
        failing.analyse(ctx())
    assert failing.interpreter.context["x"] == 0  # rolled back
    looping = chart("analyse", "send('analyse')")
    with pytest.raises(StageError, match=f"did not settle within {MAX_STEPS} steps"):
        looping.analyse(ctx())


@given(st.lists(st.floats(min_value=0, max_value=100, allow_nan=False), min_size=1, max_size=20))
def test_the_chart_keeps_its_own_variables_between_iterations(temperatures):
    """For any sequence of iterations, a counter the chart keeps counts them all."""
    stage = chart("monitor", "x += 1\n          send('monitored', count=x)")
    for i, value in enumerate(temperatures):
        assert stage.monitor(ctx(float(i), temperature=value)) == {"count": i + 1}


WAITING = """statechart:
  name: patience
  root state:
    name: root
    initial: calm
    states:
      - name: calm
        transitions:
          - {event: analyse, target: waiting, action: "send('no_anomaly')"}
      - name: waiting
        transitions:
          - {event: analyse, guard: "after(wait)", target: calm,
             action: "send('anomaly', reason='waited')"}
          - {event: analyse, guard: "not after(wait)", action: "send('no_anomaly')"}
"""


@given(
    start=st.integers(0, 10**6),
    period=st.sampled_from([0.1, 0.05, 0.2, 0.3, 0.7]),
    turns=st.integers(1, 20),
)
def test_a_timer_of_a_stage_chart_holds_on_the_iteration_of_its_deadline(start, period, turns):
    # the loop's iterations come at start + n * period, in binary arithmetic (0.1 * 7 is
    # 0.7000000000000001); after(turns * period) holds on the iteration turns after the entry
    stage = ChartStage(load_statechart(text=WAITING), "analyse")
    stage.interpreter.context["wait"] = float(f"{turns * period:.2f}")
    times = [start * period + n * period for n in range(turns + 1)]
    answers = [stage.analyse(ctx(t)) for t in times]
    assert answers[:-1] == [None] * turns
    assert answers[-1] == Anomaly("waited", {})



def test_the_time_a_stage_chart_reads_is_the_decimal_of_the_iteration_time():
    stage = chart("monitor", "send('monitored', seen=time, late=time >= 0.3)")
    assert stage.monitor(ctx(0.1 * 3)) == {"seen": 0.3, "late": True}  # 0.30000000000000004


OUTCOMES = sorted({o for outcomes in STAGE_OUTCOMES.values() for o in outcomes})


@given(
    st.sampled_from(sorted(STAGE_OUTCOMES)),
    st.sampled_from([*OUTCOMES, "go_on", "tick", "stale"]),
    st.booleans(),
)
def test_lint_refuses_exactly_the_sends_a_stage_does_not_allow(tmp_path_factory, stage, event,
                                                               takes_it):
    """For any stage and any event sent beside a proper answer: refused when it is no outcome
    of the stage, unless it is no outcome at all and the chart takes it itself."""
    answer = STAGE_OUTCOMES[stage][0]
    extra = f"\n      - event: {event}" if takes_it else ""
    text = f"""statechart:
  name: s
  root state:
    name: root
    transitions:
      - event: {stage}
        action: |
          send('{event}')
          send('{answer}'){extra}
"""
    path = tmp_path_factory.mktemp("chart") / "stage.yaml"
    path.write_text(text)
    problems = stage_chart_problems(stage, path)
    allowed = event in STAGE_OUTCOMES[stage] or (takes_it and event not in OUTCOMES)
    assert (problems == []) == allowed, problems
    if not allowed:
        assert [(p.location.line, p.location.col) for p in problems] == [(8, 11)]
