"""A replacement for a platform chart must honour the chart's interface (statecharts/
interfaces.json): `rasm lint` and `rasm run` refuse one that does not, at its place."""

from __future__ import annotations

import inspect
import re
import shutil
import subprocess
import sys

import pytest

from rasm.lint import lint_paths
from rasm.platform import (
    adaptation_manager,
    adaptation_orchestrator,
    core,
    fallback,
    storage_manager,
    trustworthiness_checker,
    trustworthiness_manager,
)
from rasm.platform.app_charts import interface_of, interface_problems, platform_chart_names
from rasm.resources import data_dir, platform_chart

from .conftest import HOTBOX

DRIVERS = [
    adaptation_manager.AdaptationManager,
    adaptation_orchestrator.AdaptationOrchestrator,
    core.Core,
    fallback.FallbackSwitch,
    storage_manager.StorageManager,
    trustworthiness_checker.TrustworthinessChecker,
    trustworthiness_manager.TrustworthinessManager,
]


def test_every_platform_chart_has_an_interface():
    shipped = sorted(p.stem for p in data_dir("statecharts").glob("*.yaml"))
    assert platform_chart_names() == shipped


@pytest.mark.parametrize("name", platform_chart_names())
def test_the_shipped_chart_honours_its_own_interface(name):
    assert interface_problems(name, platform_chart(name)) == []


@pytest.mark.parametrize("driver", DRIVERS, ids=lambda d: d.__name__)
def test_the_interface_declares_every_state_the_driver_does_work_in(driver):
    hooks = {n.removeprefix("on_enter_") for n, _ in inspect.getmembers(driver)
             if n.startswith("on_enter_")}
    assert hooks and hooks <= set(interface_of(driver.chart_name)["states"])
    # and the events it posts to its chart by name
    posted = set(re.findall(r"self\.(?:post|send)\(\"(\w+)\"", inspect.getsource(driver)))
    assert posted <= set(interface_of(driver.chart_name)["receives"])


def test_an_outcome_taken_in_the_wrong_state_is_refused_at_the_state(tmp_path):
    # `accepted` still exists, but leaves `idle` instead of `legitimating`
    app = app_with(tmp_path, "target: executing\n                event: accepted",
                   "target: executing\n                event: accepted_elsewhere")
    chart = (app / "my_orchestrator.yaml").read_text()
    (app / "my_orchestrator.yaml").write_text(chart.replace(
        "              - target: monitoring\n                event: tick",
        "              - target: executing\n                event: accepted\n"
        "              - target: monitoring\n                event: tick", 1))
    lines = (app / "my_orchestrator.yaml").read_text().splitlines()
    line = next(i for i, t in enumerate(lines, 1) if t.strip() == "- name: legitimating")
    col = lines[line - 1].index("legitimating") + 1
    assert lint_paths([str(app)]) == [
        f"{app / 'my_orchestrator.yaml'}:{line}:{col}: no transition on 'accepted' leaves "
        "state 'legitimating' (nor a state around it): the platform sends 'accepted' to its "
        "adaptation_orchestrator chart in 'legitimating', where it would be ignored"
    ]


def app_with(tmp_path, old: str, new: str):
    """The Hotbox with an orchestrator chart in which ``old`` is written ``new``."""
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    chart = platform_chart("adaptation_orchestrator").read_text()
    assert old in chart
    (app / "my_orchestrator.yaml").write_text(chart.replace(old, new))
    manifest = (app / "app.yaml").read_text()
    (app / "app.yaml").write_text(
        manifest + "statecharts:\n  adaptation_orchestrator: my_orchestrator.yaml\n"
    )
    return app


def root_line(app) -> int:
    lines = (app / "my_orchestrator.yaml").read_text().splitlines()
    return next(i for i, line in enumerate(lines, 1) if "name: lifecycle" in line)


def test_a_renamed_stage_state_is_refused_by_lint_at_the_chart(tmp_path):
    app = app_with(tmp_path, "analysing", "analyzing")
    problems = lint_paths([str(app)])
    where = f"{app / 'my_orchestrator.yaml'}:{root_line(app)}:"
    assert [p for p in problems if p.startswith(where)] == [
        f"{where}5: this replacement for the platform's adaptation_orchestrator chart has no "
        "state 'analysing': the platform relies on it (its adaptation_orchestrator chart's "
        "interface: states lifecycle, instantiated, configuration, initialization, "
        "initialized, fault, terminated, idle, monitoring, analysing, planning, legitimating, "
        "executing)"
    ]


def test_a_missing_outcome_event_is_refused_by_lint(tmp_path):
    app = app_with(tmp_path, "event: accepted", "event: approved")
    problems = lint_paths([str(app)])
    assert any(
        "has no transition on 'accepted': the platform sends it that event" in p
        and p.startswith(f"{app / 'my_orchestrator.yaml'}:{root_line(app)}:5:")
        for p in problems
    ), problems


def test_a_replacement_that_never_sends_what_the_platform_listens_for_is_refused(tmp_path):
    app = app_with(tmp_path, "send('adaptation_cancelled'", "send('adaptation_given_up'")
    problems = lint_paths([str(app)])
    assert any("never sends 'adaptation_cancelled'" in p for p in problems), problems


def test_rasm_run_refuses_a_broken_replacement_with_exit_2_and_no_traceback(tmp_path):
    app = app_with(tmp_path, "analysing", "analyzing")
    run = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--clock", "simulated",
         "--duration", "5"],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
    )
    assert run.returncode == 2, run.stdout + run.stderr
    assert f"my_orchestrator.yaml:{root_line(app)}:5: this replacement" in run.stderr
    assert "Traceback" not in run.stderr + run.stdout


def test_an_unknown_platform_chart_name_is_refused_at_its_key(tmp_path):
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    shutil.copy(platform_chart("telegraf"), app / "mine.yaml")
    text = (app / "app.yaml").read_text() + "statecharts:\n  telegraff: mine.yaml\n"
    (app / "app.yaml").write_text(text)
    line = len(text.splitlines())
    assert any(
        p.startswith(f"{app / 'app.yaml'}:{line}:")
        and "'telegraff' is not a platform chart" in p
        for p in lint_paths([str(app)])
    )


def test_a_copy_named_like_a_platform_chart_is_held_to_its_interface_when_linted_alone(tmp_path):
    chart = platform_chart("adaptation_orchestrator").read_text()
    copy = tmp_path / "my_orchestrator.yaml"
    copy.write_text(chart.replace("event: no_plan", "event: nothing_planned"))
    [problem] = lint_paths([str(copy)])
    assert problem.endswith(
        "this replacement for the platform's adaptation_orchestrator chart has no transition on "
        "'no_plan': the platform sends it that event, which would be ignored"
    )
    assert lint_paths([str(data_dir("statecharts"))]) == []  # the shipped ones honour theirs


def test_a_replacement_without_the_stage_timeouts_is_refused(tmp_path):
    # an overrunning stage ends its iteration only by the chart's timeout: without it the loop
    # would sit in the stage for good
    app = app_with(tmp_path, "send('stage_timeout'", "send('stage_over'")
    assert any("never sends 'stage_timeout'" in p for p in lint_paths([str(app)]))
