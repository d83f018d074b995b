"""Statechart-first models: stages written as charts, the managed system's modes chart and the
modes its effectors apply in, from the model to a running app."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from rasm.cli import main
from rasm.platform.manifest import load_manifest
from rasm.workflow import lint_model, new_app, package_app

from .helpers import HOTBOX_MODEL, ROOT, forget_apps, position

LIDAR_MODEL = ROOT / "examples" / "models" / "lidar_watch.yaml"
STAGE_CLASSES = ("class Monitor", "class Analyse", "class PlanComponent", "class Legitimate",
                 "class Execute")


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)  # rasm run keeps its state under ./.rasm
    forget_apps()
    yield
    forget_apps()


def rasm(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rasm.cli", *args],
        cwd=cwd, capture_output=True, text=True, timeout=300,
    )


def records(trace: Path) -> list[dict]:
    return [json.loads(line) for line in trace.read_text().splitlines()]


@pytest.mark.slow
def test_every_stage_a_chart_and_a_modes_chart_lint_run_and_pass_the_generated_tests(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["lint", str(LIDAR_MODEL)]) == 0
    assert main(["new", "lw", "--from", str(LIDAR_MODEL)]) == 0
    app = tmp_path / "lw"
    out = capsys.readouterr().out
    charts = [f"charts/{s}.yaml" for s in ("monitor", "analyse", "plan", "legitimate", "execute")]
    for name in [*charts, "lidar_modes.yaml"]:
        assert f"wrote lw/{name}" in out
    # no stage is Python: components.py holds the managed system alone
    components = (app / "components.py").read_text()
    assert not any(cls in components for cls in STAGE_CLASSES)
    assert "class Lidar:" in components and "class Simulator:" in components
    manifest = load_manifest(app)
    assert manifest.components == dict(
        zip(("monitor", "analyse", "plan", "legitimate", "execute"), charts, strict=True)
    )
    assert manifest.produces["plan"] == {"restart": "bool"}  # a Plan chart declares them too
    assert manifest.modes == app / "lidar_modes.yaml"
    assert manifest.effectors["lidar"].modes == ("stale",)
    assert main(["lint", str(app)]) == 0

    done = rasm("run", "lw", "--clock", "simulated", "--duration", "10", "--trace", "t.jsonl",
                cwd=tmp_path)
    assert done.returncode in (0, 1), done.stdout + done.stderr
    trace = records(tmp_path / "t.jsonl")
    # the modes chart ran: its initial mode is the trace's first word on the modes
    assert trace[0] == {"time": 0, "mode": "scanning", "mode_scanning": True, "mode_stale": False}
    # every iteration's monitor and analyse charts answered (a chart that does not fails its
    # stage, and the trace says so); nothing was planned, as the skeleton says
    stages = [r["stage"] for r in trace if "stage" in r]
    assert stages.count("monitor") == stages.count("analyse") == 50
    assert not any("stage failed" in str(r.get("explanation", "")) for r in trace)
    assert not any("planned" in r or "anomaly" in r for r in trace)

    tests = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"],
        cwd=app, capture_output=True, text=True, timeout=300,
    )
    assert tests.returncode == 0, tests.stdout + tests.stderr


def test_a_mix_of_chart_and_python_stages(tmp_path: Path) -> None:
    text = (
        HOTBOX_MODEL.read_text()
        .replace("{role: analyse}", "{role: analyse, implementation: statechart}")
        .replace("{role: legitimate}", "{role: legitimate, implementation: statechart}")
    )
    model = tmp_path / "mix.yaml"
    model.write_text(text)
    assert lint_model(model) == []
    app = tmp_path / "mix"
    new_app(app, model)
    components = (app / "components.py").read_text()
    assert "class Analyse" not in components and "class Legitimate" not in components
    for cls in ("class Monitor:", "class PlanComponent:", "class Execute:", "class Heater:"):
        assert cls in components
    manifest = load_manifest(app)
    assert manifest.components["analyse"] == "charts/analyse.yaml"
    assert manifest.components["legitimate"] == "charts/legitimate.yaml"
    assert manifest.components["plan"] == "components:PlanComponent"
    assert main(["lint", str(app)]) == 0
    # the Python skeleton's sensors read 0 degrees: the band property is violated, as without
    # charts; the run itself works
    assert main(["run", str(app), "--clock", "simulated", "--duration", "10",
                 "--trace", "t.jsonl"]) == 1
    trace = records(tmp_path / "t.jsonl")
    assert {"monitor", "analyse"} <= {r.get("stage") for r in trace}
    assert not any("stage failed" in str(r.get("explanation", "")) for r in trace)
    ruff = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    if Path(ruff).exists():  # the generated imports fit the stages left in Python
        done = subprocess.run(
            [ruff, "check", "--isolated", "--no-cache", "--line-length", "100",
             "--select", "E,F,W,I,B,UP", "mix"],
            capture_output=True, text=True, cwd=tmp_path,
        )
        assert done.returncode == 0, done.stdout


EDITED_ANALYSE = """\
        transitions:
          - event: analyse
            guard: knowledge.get('mode') == 'scanning'
            action: |
              send('anomaly', reason='edited chart: restart while scanning')
"""
EDITED_PLAN = "send('planned', restart=True, explanation='edited plan chart')"
EDITED_EXECUTE = "send('action', effector='lidar', payload={'restart': plan['restart']})"


def test_regeneration_keeps_edited_charts_and_the_edits_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    app = tmp_path / "lw"
    new_app(app, LIDAR_MODEL)
    analyse, plan, execute = (app / f"charts/{s}.yaml" for s in ("analyse", "plan", "execute"))
    state = "      - name: watching\n"
    analyse.write_text(analyse.read_text().replace(state, state + EDITED_ANALYSE, 1))
    plan.write_text(plan.read_text().replace("send('no_plan')  # placeholder", EDITED_PLAN))
    execute.write_text(
        execute.read_text().replace("send('no_action')  # placeholder", EDITED_EXECUTE)
    )
    edited = {p: p.read_text() for p in (app / "charts").iterdir()}
    # the model changes (a description), and the app is generated again
    (app / "model.yaml").write_text(
        LIDAR_MODEL.read_text().replace("the LiDAR and its driver", "the LiDAR, its driver")
    )
    capsys.readouterr()
    assert main(["new", str(app)]) == 0
    out = capsys.readouterr().out
    assert {p: p.read_text() for p in (app / "charts").iterdir()} == edited
    assert f"kept  {analyse}" in out and f"kept  {app / 'lidar_modes.yaml'}" in out
    assert main(["lint", str(app)]) == 0
    assert main(["run", str(app), "--clock", "simulated", "--duration", "2",
                 "--trace", "t.jsonl"]) in (0, 1)
    trace = records(tmp_path / "t.jsonl")
    explanations = [str(r.get("explanation", "")) for r in trace]
    assert "edited chart: restart while scanning" in explanations
    assert "edited plan chart" in explanations
    # the effector applies only while stale: the skeleton's modes chart never leaves scanning,
    # so every restart is dropped with the mode that refused it
    assert any("not applicable in managed-system mode 'scanning'" in e for e in explanations)
    assert not any(r.get("executed") for r in trace)


def test_a_modes_chart_whose_states_changed_is_checked_against_the_model(tmp_path: Path) -> None:
    app = tmp_path / "lw"
    new_app(app, LIDAR_MODEL)
    modes = app / "lidar_modes.yaml"
    modes.write_text(modes.read_text().replace("stale", "jammed"))
    text = (app / "model.yaml").read_text()
    errors = [(e.location.line, e.location.col, e.message) for e in lint_model(app / "model.yaml")]
    states = position(text, "stale]")
    port_mode = position(text, "stale]", 2)
    assert (*states, "'stale' is not a state of the modes chart lidar_modes.yaml: change the "
            "model's states to match the chart") in errors
    assert (*port_mode, "port lidar.driver: 'stale' is not a state of the modes chart "
            "lidar_modes.yaml (its states: jammed, scanning)") in errors
    # and the property reading in_mode("stale") reads a mode the chart no longer has
    reads = position(text, 'in_mode("stale")')
    assert (*reads, "lidar.rv reads 'mode_stale', which no "
            "component produces (did you mean 'mode_jammed'?)") in errors
    assert len(errors) == 4


MODEL_ERRORS = [
    (
        "  lidar:\n    role: managed\n",
        "  lidar:\n    role: managed\n    implementation: statechart\n",
        "implementation: statechart",
        len("implementation: "),
        "'lidar' is a managed: only a MAPLE-K stage can be a statechart",
    ),
    (
        "  analyse: {role: analyse, implementation: statechart}",
        "  analyse: {role: analyse, modes: {states: [busy]}}",
        "modes: {states: [busy]}",
        0,
        "'analyse' is the analyse stage: modes belong to the managed system",
    ),
    (
        "modes: [stale]",
        "modes: [stal]",
        "stal]",
        0,
        "port lidar.driver: 'stal' is not a state of the modes chart lidar_modes.yaml (its "
        "states: scanning, stale): did you mean 'stale'?",
    ),
    (
        "      scan: {direction: out, message: Scan}",
        "      scan: {direction: out, message: Scan, modes: [stale]}",
        "stale]}",
        0,
        "port lidar.scan: modes apply to the actions of the execute stage",
    ),
    (
        "states: [scanning, stale]",
        "states: [scanning, lidar]",
        "lidar]",
        0,
        "state 'lidar' is the modes chart's root",
    ),
    (
        "      motor_rpm: {type: float, min: 0}",
        "      motor_rpm: {type: float, min: 0}\n      mode_stale: {type: bool}",
        "mode_stale: {type",
        0,
        "signal 'mode_stale': the modes chart writes it",
    ),
    (
        "chart: lidar_modes.yaml",
        "chart: ../lidar_modes.yaml",
        "../lidar_modes.yaml",
        0,
        "the modes chart ../lidar_modes.yaml must be a path inside the application folder",
    ),
    (
        "chart: lidar_modes.yaml",
        "chart: charts/analyse.yaml",
        "charts/analyse.yaml",
        0,
        "the modes chart charts/analyse.yaml is also the file of 'analyse'",
    ),
    (
        "    - file: lidar.rv",
        "    - file: charts/plan.yaml",
        "implementation: statechart, produces",
        len("implementation: "),
        "the chart of 'plan', charts/plan.yaml, is also a trustworthiness file",
    ),
    (
        "produces: {restart: bool}",
        "produces: {restart: bool, mode: str}",
        "mode: str",
        0,
        "signal 'mode': the modes chart writes it",
    ),
    (
        "  analyse: {role: analyse, implementation: statechart}",
        "  analyse: {role: analyse, implementation: chart}",
        "chart}",
        0,
        "components.analyse.implementation: 'chart' is not one of ['python', 'statechart']",
    ),
    (
        "states: [scanning, stale]",
        "states: [scanning, Stale]",
        "Stale]",
        0,
        "components.lidar.modes.states.1: 'Stale' does not match",
    ),
]


@pytest.mark.parametrize(
    ("old", "new", "needle", "offset", "message"),
    MODEL_ERRORS,
)
def test_lint_errors_for_the_new_keys_name_their_position(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
    old: str, new: str, needle: str, offset: int, message: str,
) -> None:
    source = LIDAR_MODEL.read_text()
    assert old in source
    text = source.replace(old, new, 1)
    model = tmp_path / "model.yaml"
    model.write_text(text)
    line, col = position(text, needle)
    errors = [(e.location.line, e.location.col, e.message) for e in lint_model(model)]
    assert any(
        (ln, cl) == (line, col + offset) and m.startswith(message) for ln, cl, m in errors
    ), errors
    # the command line: lint reports it (exit 1), new refuses the model (exit 2), no traceback
    capsys.readouterr()
    assert main(["lint", str(model)]) == 1
    assert f"{model}:{line}:{col + offset}: {message}" in capsys.readouterr().out
    assert main(["new", "x", "--from", str(model)]) == 2
    err = capsys.readouterr().err
    assert f"{model}:{line}:{col + offset}: {message}" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_effector_modes_need_a_modes_chart_and_a_modes_chart_replaces_mode_signal(
    tmp_path: Path,
) -> None:
    source = LIDAR_MODEL.read_text()
    start = source.index("    modes:                        # the managed system's modes chart")
    end = source.index("    ports:\n      scan:")
    without = source[:start] + source[end:]
    model = tmp_path / "model.yaml"
    model.write_text(without)
    line, col = position(without, "stale]")
    error = lint_model(model)[0]  # then the property's in_mode("stale"), twice
    assert (error.location.line, error.location.col) == (line, col)
    assert error.message.startswith("port lidar.driver applies in modes, but the managed system "
                                    "has no modes chart")

    # modes on a port the execute stage does not send to, with no modes chart: said, not raised
    astray = without.replace("scan: {direction: out, message: Scan}",
                             "scan: {direction: out, message: Scan, modes: [stale]}")
    model.write_text(astray)
    line, col = position(astray, "stale]}")
    errors = [e for e in lint_model(model) if e.message.startswith("port lidar.scan")]
    assert [(e.location.line, e.location.col) for e in errors] == [(line, col)]
    assert "no row of the communication matrix sends them here" in errors[0].message

    both = source.replace("trustworthiness:                  # trustworthiness definition\n",
                          "trustworthiness:                  # trustworthiness definition\n"
                          "  mode_signal: motor_rpm\n")
    model.write_text(both)
    line, col = position(both, "mode_signal")
    [error] = lint_model(model)
    assert (error.location.line, error.location.col) == (line, col)
    assert "modes are its modes chart: leave out mode_signal" in error.message

    second = source.replace(
        "  monitor:\n    role: monitor\n",
        "  spare:\n    role: probe\n    modes: {states: [on]}\n"
        "    ports:\n      out: {direction: out, message: Status}\n"
        "  monitor:\n    role: monitor\n",
    ).replace(
        "status: {direction: in, message: Status}",
        "status: {direction: in, message: Status}\n      spare: {direction: in, message: Status}",
    )
    second = second.replace(
        "  - {topic: lidar/driver,",
        "  - {topic: spare/status, publisher: spare.out, subscribers: [monitor.spare]}\n"
        "  - {topic: lidar/driver,",
    ).replace("execute: robot}", "execute: robot, spare: robot}")
    model.write_text(second)
    line, col = position(second, "modes: {states: [on]}")
    errors = lint_model(model)
    assert [(e.location.line, e.location.col) for e in errors] == [(line, col)], errors
    assert "'lidar' already does: the managed system has one modes chart" in errors[0].message


SILENT_ANALYSE = """\
        transitions:
          - event: analyse
            guard: knowledge.get('ranges', 0) > 300
            action: |
              pass
"""
FRAGILE_MODES = 'guard: 1 / event.data.get("motor_rpm", 1) < 0  # never holds, fails at 0 rpm'


@pytest.mark.slow
def test_the_generated_chart_tests_find_the_readings_a_chart_fails_on(tmp_path: Path) -> None:
    app = tmp_path / "lw"
    new_app(app, LIDAR_MODEL)
    analyse = app / "charts" / "analyse.yaml"
    state = "      - name: watching\n"
    analyse.write_text(analyse.read_text().replace(state, state + SILENT_ANALYSE, 1))
    modes = app / "lidar_modes.yaml"
    modes.write_text(modes.read_text().replace('guard: "False"  # placeholder', FRAGILE_MODES, 1))
    assert main(["lint", str(app)]) == 0  # nothing a static check can see
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests", "-k", "chart"],
        cwd=app, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert "2 failed" in done.stdout, done.stdout
    # hypothesis shrinks to the reading each chart fails on
    assert "sent no outcome" in done.stdout and "(ranges): 301" in done.stdout
    assert "the modes chart failed on the record {'motor_rpm': 0.0}" in done.stdout


def test_a_stage_turned_into_a_chart_keeps_its_python_code_among_the_orphans(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    app = tmp_path / "hb"
    new_app(app, HOTBOX_MODEL)
    components = app / "components.py"
    end = "        # <<< rasm:user PlanComponent.plan"
    components.write_text(components.read_text().replace(
        "        return None  # placeholder\n" + end, "        return MY_PLAN\n" + end
    ))
    model = app / "model.yaml"
    model.write_text(model.read_text().replace(
        "{role: plan}", "{role: plan, implementation: statechart}"
    ))
    capsys.readouterr()
    assert main(["new", str(app)]) == 0
    captured = capsys.readouterr()
    assert f"wrote {app / 'charts/plan.yaml'}" in captured.out
    assert "class PlanComponent" not in components.read_text()
    assert "region PlanComponent.plan could not be kept" in captured.err
    assert "return MY_PLAN" in (app / ".rasm-orphans" / "components.py.txt").read_text()
    assert load_manifest(app).components["plan"] == "charts/plan.yaml"
    assert main(["lint", str(app)]) == 0


@pytest.mark.slow
def test_the_package_of_a_statechart_app_carries_its_charts(tmp_path: Path) -> None:
    app = tmp_path / "lw"
    new_app(app, LIDAR_MODEL)
    package_app(app, tmp_path / "lw.zip", dependencies=False)
    with zipfile.ZipFile(tmp_path / "lw.zip") as package:
        node = package.read("02_Nodes/maple_k/analyse/analyse.yaml").decode()
        [wheel] = [n for n in package.namelist() if n.startswith("01_Binaries/rasm_app_")]
        (tmp_path / "app.whl").write_bytes(package.read(wheel))
    assert "implementation: charts/analyse.yaml" in node
    with zipfile.ZipFile(tmp_path / "app.whl") as wheel_file:
        names = set(wheel_file.namelist())
    for chart in ("charts/monitor.yaml", "charts/execute.yaml", "lidar_modes.yaml"):
        assert f"rasm_app_lidar_watch/{chart}" in names


STATECHARTS_GUIDE = (ROOT / "docs" / "statecharts.md").read_text(encoding="utf-8")

# the managed system of the example model publishes a scan every step, with no rays while jammed
LIDAR_CODE = {
    "Lidar.__init__": """\
        self.jams = sorted(scenario.get("jams", []))
        self.jammed = False
""",
    "Lidar.scan": """\
        if self.jams and time >= self.jams[0]:
            self.jams.pop(0)
            self.jammed = True
        return messages.Scan(ranges=0 if self.jammed else 360)
""",
    "Lidar.status": "        return messages.Status(motor_rpm=600.0)\n",
    "Lidar.on_driver": """\
        if message.restart:
            self.jammed = False
""",
}


def tutorial_block(label: str) -> str:
    found = re.search(rf"<!-- tutorial: {re.escape(label)} -->\n```\w+\n(.*?)```",
                      STATECHARTS_GUIDE, re.S)
    assert found, f"no tutorial block '{label}'"
    return found.group(1)


def test_the_tutorials_charts_written_into_the_example_models_app_restart_the_lidar(
    tmp_path: Path,
) -> None:
    """The skeleton of examples/models/lidar_watch.yaml is the tutorial's app, to be written:
    with the guide's stage charts and modes chart in it, it runs as the guide says."""
    app = tmp_path / "lw"
    new_app(app, LIDAR_MODEL)
    for stage in ("monitor", "analyse", "plan", "legitimate", "execute"):
        chart = tutorial_block(f"lidar_watch/charts/{stage}.yaml")
        (app / "charts" / f"{stage}.yaml").write_text(chart)
    # a jammed scan has no rays here, where the guide's simulator sends no scan at all
    (app / "lidar_modes.yaml").write_text(
        tutorial_block("lidar_watch/lidar_modes.yaml").replace(
            "\"'ranges' in event.data\"", "event.data.get('ranges', 0) > 0"
        )
    )
    components = app / "components.py"
    text = components.read_text()
    for region, code in LIDAR_CODE.items():
        start = f"# >>> rasm:user {region}\n"
        end = f"        # <<< rasm:user {region}"
        body = text[text.index(start) + len(start):text.index(end)]
        text = text.replace(start + body + end, start + code + end)
    components.write_text(text)
    assert main(["lint", str(app)]) == 0
    assert main(["run", str(app), "--clock", "simulated", "--trace", "t.jsonl"]) == 0
    trace = records(tmp_path / "t.jsonl")
    anomalies = [r["time"] for r in trace if r.get("anomaly")]
    executed = [r["time"] for r in trace if r.get("executed")]
    assert len(anomalies) == len(executed) == 2, (anomalies, executed)
    # stale half a second after the last scan with rays (jams at 2 s and 6 s; a scan every
    # 0.1 s); Analyse sees it at the next iteration, and the restart goes out at once
    stale = [r["time"] for r in trace if r.get("mode_stale") is True]
    assert [round(t, 1) for t in stale] == [2.4, 6.4]
    assert all(0 <= a - s <= 0.2 for s, a in zip(stale, anomalies, strict=True))
    assert executed == anomalies
