"""The statechart guide's app (docs/statecharts.md, step 6) runs as the guide says: its stages
are charts, its managed system's modes are a chart, on the simulated and the wall clock; the
modes gate its effector; a stage chart that does not answer fails its stage; and lint refuses a
stage chart that sends what its stage does not allow, or effector modes the chart lacks."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from rasm import Platform, RunOptions
from rasm.knowledge import KnowledgeBase
from rasm.lint import lint_paths
from rasm.loop import ROBUSTNESS_PREFIX
from rasm.platform.chart_stages import ChartStage
from rasm.platform.components import StageContext

from .support import REPO

DOC = (REPO / "docs" / "statecharts.md").read_text(encoding="utf-8")
BLOCK = re.compile(r"<!-- tutorial: (lidar_watch/[\w/.]+) -->\n```\w+\n(.*?)```", re.S)


def write_app(folder: Path) -> Path:
    """The guide's app, written from the guide's own blocks."""
    blocks = BLOCK.findall(DOC)
    assert {name for name, _ in blocks} >= {"lidar_watch/app.yaml", "lidar_watch/lidar_modes.yaml"}
    for name, text in blocks:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return folder / "lidar_watch"


@pytest.fixture
def app(tmp_path):
    return write_app(tmp_path)


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert text.count(old) == 1, old
    path.write_text(text.replace(old, new), encoding="utf-8")


def run(app: Path, tmp_path: Path, clock: str = "simulated", duration: float | None = None):
    trace = tmp_path / f"{clock}.jsonl"
    platform = Platform(app, RunOptions(clock=clock, seed=1, trace=trace,
                                        state_dir=tmp_path / "state"))
    summary = platform.run(duration)
    return summary, [json.loads(line) for line in trace.read_text().splitlines()]


def test_the_guide_app_lints_clean(app):
    assert lint_paths([str(app)]) == []


def without_robustness(trace: list[dict]) -> list[dict]:
    """The records without the robustness the Trustworthiness Checker adds to them."""
    return [{k: v for k, v in r.items() if not k.startswith(ROBUSTNESS_PREFIX)} for r in trace]


def test_the_guide_app_restarts_the_jammed_driver_on_the_simulated_clock(app, tmp_path):
    summary, trace = run(app, tmp_path)
    assert summary.stats.anomalies == 2 and summary.stats.executed == 2
    assert set(summary.verdicts.values()) == {"satisfied"}
    assert not summary.stats.timeouts and not summary.stats.failed_stages
    # the records the guide shows are in the trace, as shown
    shown = re.search(r"at once[^:]*:\n\n```json\n(.*?)```", DOC, re.S).group(1)
    for line in shown.splitlines():  # the guide leaves out the properties' robustness
        assert json.loads(line) in without_robustness(trace), line
    # every restart went out while the LiDAR was stale
    mode = None
    for record in trace:
        mode = record.get("mode", mode)
        if record.get("executed"):
            assert mode == "stale"


@pytest.mark.slow
def test_the_guide_app_runs_on_the_wall_clock(app, tmp_path):
    edit(app / "app.yaml", "scenario: {jams: [2.0, 6.0]}", "scenario: {jams: [1.0]}")
    summary, trace = run(app, tmp_path, "wall", 2.5)
    assert summary.stats.executed >= 1
    modes = [r["mode"] for r in trace if "mode" in r]
    assert modes[:3] == ["scanning", "stale", "scanning"]


def test_a_mode_that_forbids_the_effector_really_stops_the_action(app, tmp_path):
    edit(app / "app.yaml", "modes: [stale]", "modes: [scanning]")
    summary, trace = run(app, tmp_path)
    assert summary.stats.executed == 0 and summary.stats.dropped >= 1
    dropped = {r["explanation"] for r in trace if r.get("dropped")}
    assert dropped == {"not applicable in managed-system mode 'stale' (lidar applies in scanning)"}
    # the driver stayed jammed: no scan after the first jam, and the property says so
    assert not [r for r in trace if r.get("ranges") and r["time"] > 2.2]
    assert summary.verdicts["scans_come_back"] == "violated"


def test_a_stage_chart_that_does_not_answer_fails_its_stage_like_an_overrun(app, tmp_path):
    edit(
        app / "charts" / "analyse.yaml",
        "    transitions:\n      - event: analyse              # no transition of the active "
        "state took it\n        action: |\n          send('no_anomaly')\n",
        "",
    )
    summary, trace = run(app, tmp_path)
    assert summary.stats.timeouts["analyse"] > 10
    assert summary.stats.executed >= 2  # the iterations that raised went on as before
    why = [r["explanation"] for r in trace if "failed to answer" in r.get("explanation", "")]
    assert why and why[0].startswith(
        "analyse stage failed to answer: the analyse chart 'analyse' sent no outcome"
    )
    # nothing follows an unanswered analyse in its iteration
    for i, record in enumerate(trace):
        if "failed to answer" in record.get("explanation", ""):
            later = [r for r in trace[i + 1:] if r["time"] == record["time"]]
            assert not any(r.get("planned") or r.get("stage") == "plan" for r in later)


def test_lint_refuses_a_stage_chart_sending_an_outcome_its_stage_does_not_allow(app):
    chart = app / "charts" / "execute.yaml"
    edit(chart, "send('action', effector", "send('accepted', effector")
    line = next(i for i, t in enumerate(chart.read_text().splitlines(), 1) if "send(" in t)
    assert lint_paths([str(app)]) == [
        f"{chart}:5:5: this chart for the execute stage never sends an outcome: it answers "
        "'execute' with send() of 'action' or 'no_action'",
        f"{chart}:{line}:11: 'accepted' is the legitimate stage's outcome, not an outcome of "
        "the execute stage (it answers with 'action' or 'no_action')",
    ]


def test_lint_refuses_effector_modes_the_modes_chart_does_not_have(app):
    edit(app / "app.yaml", "modes: [stale]", "modes: [stall]")
    line = next(
        i for i, t in enumerate((app / "app.yaml").read_text().splitlines(), 1)
        if "modes: [stall]" in t
    )
    assert lint_paths([str(app)]) == [
        f"{app / 'app.yaml'}:{line}:13: effector lidar: 'stall' is not a state of the modes "
        "chart: did you mean 'stale'?"
    ]


def test_a_stage_chart_keeps_its_state_between_iterations_and_reads_the_context(app):
    analyse = ChartStage(app / "charts" / "analyse.yaml", "analyse")
    kb = KnowledgeBase()
    kb.register_knowledge("mode", "stale", 0.0)
    assert analyse.analyse(StageContext(kb, 1.0, 1)).reason.startswith("no scan")
    assert analyse.analyse(StageContext(kb, 2.0, 2)) is None  # retry_after: 2 s
    assert analyse.analyse(StageContext(kb, 3.0, 3)).reason.startswith("still no scan")
    kb.register_knowledge("mode", "scanning", 3.5)
    assert analyse.analyse(StageContext(kb, 4.0, 4)) is None
    assert set(analyse.interpreter.configuration) == {"analysing", "watching"}


@pytest.mark.slow
def test_a_stage_chart_over_its_budget_on_the_wall_clock_fails_its_stage(app, tmp_path):
    edit(app / "app.yaml", "  period: 0.2\n", "  period: 0.2\n  stage_budget: 0.1\n")
    edit(app / "app.yaml", "scenario: {jams: [2.0, 6.0]}", "scenario: {jams: [0.5]}")
    edit(
        app / "charts" / "plan.yaml",
        "        action: |\n",
        "        action: |\n          import time\n          time.sleep(0.3)\n",
    )
    summary, trace = run(app, tmp_path, "wall", 2.0)
    assert summary.stats.timeouts["plan"] >= 1
    assert summary.stats.executed == 0  # no plan ever came in time
    assert any(r.get("explanation") == "plan stage overran its time budget" for r in trace)


def test_the_modes_chart_timer_fires_when_no_record_comes_at_all(app, tmp_path):
    # a jam now silences the whole LiDAR: nothing is stored, yet it goes stale on time
    edit(
        app / "simulator.py",
        'readings = {"lidar/status": {"motor_rpm": 600.0}}',
        'readings = {} if self.jammed else {"lidar/status": {"motor_rpm": 600.0}}',
    )
    summary, trace = run(app, tmp_path)
    changes = [(r["time"], r["mode"]) for r in trace if "mode" in r]
    assert changes[:3] == [(0, "scanning"), (2.3, "stale"), (2.6, "scanning")]
    assert [r for r in without_robustness(trace) if r["time"] == 2.3] == [
        {"time": 2.3, "mode": "stale", "mode_stale": True, "mode_scanning": False}
    ]
    assert summary.stats.executed == 2


def test_lint_refuses_an_execute_chart_acting_on_an_effector_the_app_lacks(app):
    chart = app / "charts" / "execute.yaml"
    edit(chart, "effector='lidar'", "effector='lidr'")
    line = next(i for i, t in enumerate(chart.read_text().splitlines(), 1) if "lidr" in t)
    col = chart.read_text().splitlines()[line - 1].index("'lidr'") + 1
    assert lint_paths([str(app)]) == [
        f"{chart}:{line}:{col}: effector 'lidr' is not an effector of the app: did you mean "
        "'lidar'?"
    ]


def test_the_guides_stage_chart_test_runs_as_written(monkeypatch):
    snippet = re.search(r"\*\*Testing a stage chart\.\*\*.*?```python\n(.*?)```", DOC, re.S)
    monkeypatch.chdir(REPO)  # "run from the repository's root"
    exec(compile(snippet.group(1), "statecharts.md", "exec"), {})
