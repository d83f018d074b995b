"""Every mistake in app.yaml is reported at its line and column, with exit code 2."""

from __future__ import annotations

import shutil
import textwrap

import pytest

from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.platform.manifest import load_manifest

from .conftest import HOTBOX

GOOD = """\
name: demo
components:
  monitor: components:M
  analyse: components:A
  plan: components:P
  execute: components:E
probes:
  - topic: demo/sensors
    signals:
      x: {type: float, min: 0, max: 10}
effectors:
  valve: {topic: demo/valve}
loop:
  period: 0.5
"""


def write_app(tmp_path, text):
    (tmp_path / "app.yaml").write_text(textwrap.dedent(text))
    (tmp_path / "components.py").write_text(
        "class M: pass\nclass A: pass\nclass P: pass\nclass E: pass\n"
    )
    return tmp_path


def errors(tmp_path, text):
    with pytest.raises(SourceErrors) as info:
        load_manifest(write_app(tmp_path, text))
    return [(e.location.line, e.location.col, e.message) for e in info.value.errors]


def test_a_good_manifest_loads(tmp_path):
    manifest = load_manifest(write_app(tmp_path, GOOD))
    assert manifest.name == "demo" and manifest.period == 0.5
    assert manifest.signals["x"].maximum == 10


@pytest.mark.parametrize(
    "old, new, line, col, message",
    [
        ("name: demo", "name: 3demo", 1, 7, "does not match"),
        ("  plan: components:P\n", "", 2, 1, "'plan' is a required property"),
        (
            "  execute: components:E",
            "  execute: components:E\n  pan: components:P",
            7,
            3,
            "unknown key 'pan' in components",
        ),
        (
            "x: {type: float, min: 0, max: 10}",
            "x: {type: double}",
            10,
            17,
            "'double' is not one of",
        ),
        ("  period: 0.5", "  period: -1", 14, 11, "less than the minimum of 1e-06"),
        ("  period: 0.5", "  period: 0.5\n  max_actions: 0", 15, 16, "less than the minimum of 1"),
        ("loop:\n", "timing: offf\nloop:\n", 13, 9, "does not match"),
        ("  monitor: components:M", "  monitor: components.M", 3, 12, "is not module:Class"),
        (
            "x: {type: float, min: 0, max: 10}",
            "x: {type: float, min: 5, max: 1}",
            10,
            7,
            "min is above max",
        ),
        (  # a probe signal would forge the loop's own events in the trace
            "x: {type: float, min: 0, max: 10}",
            "executed: {type: bool}",
            10,
            7,
            "signal 'executed': a key the loop writes itself in the trace (anomaly, broken_rules",
        ),
        (  # ... and one named robustness_* the margin a stage adapts on
            "x: {type: float, min: 0, max: 10}",
            "robustness_band: {type: float}",
            10,
            7,
            "signal 'robustness_band': the Trustworthiness Checker writes robustness_<property>",
        ),
    ],
)
def test_each_mistake_is_reported_at_its_place(tmp_path, old, new, line, col, message):
    assert old in GOOD
    found = errors(tmp_path, GOOD.replace(old, new))
    assert any(message in m and (ln, c) == (line, col) for ln, c, m in found), found


def test_missing_files_are_named(tmp_path):
    found = errors(tmp_path, GOOD + "properties: [props/missing.rv]\nrules: rules/none.yaml\n")
    assert (15, 14) in {(ln, c) for ln, c, _ in found}
    assert any("no such file: rules/none.yaml" in m for _, _, m in found)


def test_cli_run_exits_2_with_the_position_and_no_traceback(tmp_path, capsys):
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    text = (app / "app.yaml").read_text().replace("period: 0.5", "period: fast")
    (app / "app.yaml").write_text(text)
    assert main(["run", str(app), "--clock", "simulated", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    line = next(i for i, t in enumerate(text.splitlines(), 1) if "period: fast" in t)
    assert f"app.yaml:{line}:" in err and "'fast' is not of type 'number'" in err
    assert "Traceback" not in err
    assert main(["lint", str(app / "app.yaml")]) == 1


def test_cli_run_on_a_folder_without_manifest(tmp_path, capsys):
    assert main(["run", str(tmp_path)]) == 2
    assert f"no app manifest in this folder (expected {tmp_path / 'app.yaml'})" in (
        capsys.readouterr().err
    )
    # a folder that does not exist is named as such, not as a missing app.yaml inside it
    assert main(["run", str(tmp_path / "nothing")]) == 2
    assert f"no such app folder or manifest: {tmp_path / 'nothing'}" in capsys.readouterr().err


def test_cli_run_bad_scenario_exits_2_with_the_place(tmp_path, capsys):
    assert main(["run", str(HOTBOX), "--clock", "simulated", "--scenario", '{"openings": ']) == 2
    err = capsys.readouterr().err
    assert "--scenario:1:" in err and "not valid JSON" in err and "Traceback" not in err
    bad = tmp_path / "scenario.yaml"
    bad.write_text("- not\n- a mapping\n")
    assert main(["run", str(HOTBOX), "--clock", "simulated", "--scenario", str(bad)]) == 2
    assert f"{bad}:1:1: a scenario is a mapping" in capsys.readouterr().err


def test_cli_run_on_a_non_utf8_manifest_exits_2_at_the_bad_byte(tmp_path, capsys):
    (tmp_path / "app.yaml").write_bytes(b"name: caf\xe9\n")
    assert main(["run", str(tmp_path), "--clock", "simulated", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'app.yaml'}:1:10: not a UTF-8 text file" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("duration", ["nan", "inf", "1e999", "0"])
def test_cli_run_and_monitor_refuse_a_duration_that_never_ends(tmp_path, capsys, duration):
    # a simulated run of nan/inf seconds used to loop forever
    assert main(["run", str(HOTBOX), "--clock", "simulated", "--duration", duration]) == 2
    assert "--duration must be a positive, finite number" in capsys.readouterr().err
    props = tmp_path / "p.rv"
    props.write_text("input x: float\nproperty p: x < 1\n")
    assert main(["monitor", str(props), "--transport", "local", "--duration", duration]) == 2
    assert "--duration must be a positive number of seconds" in capsys.readouterr().err


def test_non_finite_numbers_in_the_manifest_are_refused_at_their_place(tmp_path):
    found = errors(tmp_path, GOOD.replace("period: 0.5", "period: .inf") + "duration: .nan\n")
    assert (14, 11, "loop.period: must be a finite number, not inf") in found
    assert (15, 11, "duration: must be a finite number, not nan") in found


def test_a_period_too_short_to_move_the_clock_is_refused_at_its_place(tmp_path):
    # 1e-300 s is positive, but added to the clock it changes nothing: the run spun forever
    found = errors(tmp_path, GOOD.replace("period: 0.5", "period: 1.0e-300"))
    assert [(line, col) for line, col, _ in found] == [(14, 11)]
    assert "1e-300 is less than the minimum of 1e-06" in found[0][2]


@pytest.mark.parametrize(
    ("ref", "message"),
    [
        (
            "components:HotboxAnalyse",
            "components.plan: components:HotboxAnalyse: HotboxAnalyse has no plan(ctx) method, "
            "so the plan stage would never run it",
        ),
        ("components:Nope", "components:Nope: components has no 'Nope'"),
    ],
)
def test_cli_run_names_the_place_of_a_component_that_cannot_be_a_stage(
    tmp_path, capsys, monkeypatch, ref, message
):
    # a class without the stage's method used to be accepted, and the stage silently did nothing
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    text = (app / "app.yaml").read_text().replace("components:HotboxPlan", ref)
    (app / "app.yaml").write_text(text)
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(app), "--clock", "simulated", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    line, col = next(
        (i, t.index(ref) + 1)
        for i, t in enumerate(text.splitlines(), 1)
        if t.strip() == f"component: {ref}"
    )
    assert err == f"rasm: {app / 'app.yaml'}:{line}:{col}: {message}\n"


def test_platform_refuses_bad_arguments_with_what_to_do(tmp_path):
    from rasm import Platform, RunOptions
    from rasm.errors import PlatformError

    class Analyser:
        def analyse(self, ctx):
            return None

    with pytest.raises(PlatformError, match=r"^unknown clock 'simulatd' \(simulated or wall\)$"):
        Platform(HOTBOX, RunOptions(clock="simulatd"))
    with pytest.raises(PlatformError, match=r"^components: unknown stage 'planner' \(the stages"):
        Platform(HOTBOX, RunOptions(components={"planner": Analyser()}))
    with pytest.raises(PlatformError, match=r"^components\['plan'\]: Analyser has no plan\(ctx\)"):
        Platform(HOTBOX, RunOptions(components={"plan": Analyser()}))
    with pytest.raises(TypeError, match=r"^components must be a dict \{stage: object\}, not list"):
        Platform(HOTBOX, RunOptions(components=[Analyser()]))
    with pytest.raises(TypeError, match=r"^Platform\(\) takes an app folder, its app.yaml or"):
        Platform(42)
    # an app folder is as good as its manifest
    platform = Platform(HOTBOX, RunOptions(clock="simulated", knowledge="memory",
                                           state_dir=tmp_path))
    assert platform.manifest.name == "hotbox"
    assert platform.run(1.0).stats.iterations == 2


def test_components_that_exit_or_do_not_parse_are_reported_not_fatal(tmp_path, capsys, monkeypatch):
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    source = (app / "components.py").read_text()
    monkeypatch.chdir(tmp_path)
    # sys.exit() at import used to end rasm run with its code and no message
    (app / "components.py").write_text(source + "\nimport sys\nsys.exit(7)\n")
    assert main(["run", str(app), "--clock", "simulated", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert err.endswith(": components:HotboxMonitor: importing components failed: SystemExit: 7\n")
    # a syntax error is reported where it is, in the Python file
    lines = source.count("\n")
    (app / "components.py").write_text(source + "def broken(:\n")
    assert main(["run", str(app), "--clock", "simulated", "--duration", "1"]) == 2
    assert capsys.readouterr().err == (
        f"rasm: {app / 'components.py'}:{lines + 1}:12: components:HotboxMonitor: "
        "SyntaxError: invalid syntax\n"
    )


@pytest.mark.parametrize("port", ["99999", "-1"])
def test_a_dashboard_port_out_of_range_exits_2(tmp_path, capsys, monkeypatch, port):
    monkeypatch.chdir(tmp_path)  # it was an OverflowError traceback from bind()
    args = ["run", str(HOTBOX), "--clock", "simulated", "--duration", "1", "--dashboard", port]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err == f"rasm: dashboard: port {port} is not a TCP port (0 to 65535)\n"


def test_the_schema_declares_the_value_types_rasm_checks():
    # the schema is also the editors' reference: its type lists are the ones rasm.values checks
    from rasm.platform.manifest import SCHEMA
    from rasm.values import TYPES

    enums = []
    stack = [SCHEMA]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            if "float" in node.get("enum", ()):
                enums.append(node["enum"])
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    assert len(enums) == 3 and all(tuple(enum) == TYPES for enum in enums)
