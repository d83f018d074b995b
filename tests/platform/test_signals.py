"""The static signal check: a property or rule reading a name no part of the app provides is
refused by `rasm lint` (exit 1) and by `rasm run` before anything starts (exit 2), at the place
of the read, with the closest provided name."""

from __future__ import annotations

import dataclasses
import keyword
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.lint import lint_paths
from rasm.platform.manifest import load_manifest
from rasm.platform.signals import app_problems, check_app, provided
from rasm.testing import run_app

from .conftest import HOTBOX, ROOT

TURTLEBOT = ROOT / "examples" / "turtlebot"


def copy_app(tmp_path: Path, source: Path = HOTBOX) -> Path:
    app = tmp_path / "app"
    # the default app alone: the extra manifests beside it (app.*.yaml) would be linted too
    shutil.copytree(
        source, app, ignore=shutil.ignore_patterns(".rasm", "__pycache__", "app.*.yaml")
    )
    return app


def edit(path: Path, old: str, new: str) -> str:
    text = path.read_text(encoding="utf-8")
    assert old in text, (path, old)
    text = text.replace(old, new)
    path.write_text(text, encoding="utf-8")
    return text


def place(text: str, needle: str) -> tuple[int, int]:
    """1-based line and column of the first ``needle`` in ``text``."""
    start = text.index(needle)
    return text.count("\n", 0, start) + 1, start - (text.rfind("\n", 0, start) + 1) + 1


def problems(app: Path) -> list[tuple[str, int, int, str]]:
    return [
        (Path(e.location.file).name, e.location.line, e.location.col, e.message)
        for e in app_problems(load_manifest(app))
    ]


# --------------------------------------------------------------------------- the examples


def test_the_examples_lint_clean_and_pass_the_check():
    assert lint_paths([str(HOTBOX), str(TURTLEBOT), str(ROOT / "examples" / "models")]) == []
    for app in (HOTBOX, TURTLEBOT):
        check_app(load_manifest(app))


def test_the_monitors_declared_signals_are_provided_and_undeclared_ones_are_not(tmp_path):
    app = copy_app(tmp_path)
    props = app / "properties" / "hotbox.rv"
    text = edit(
        props,
        "property heater_rating:",
        "property steady:\n    always (abs(temperature_trend) < 5.0)\n\nproperty heater_rating:",
    )
    assert problems(app) == []
    edit(
        app / "app.yaml",
        "produces: {temperature_mean: float, temperature_trend: float}",
        "produces: {temperature_mean: float}",
    )
    line, col = place(text, "temperature_trend")
    assert problems(app) == [
        (
            "hotbox.rv",
            line,
            col,
            "signal 'temperature_trend' is not provided by any part of the app: "
            "did you mean 'temperature_mean'?",
        )
    ]


# --------------------------------------------------------------------------- properties


def test_a_misspelled_signal_in_a_property_is_reported_at_its_use(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "properties" / "hotbox.rv", "always (heater_power <=", "always (heater_powr <="
    )
    line, col = place(text, "heater_powr")
    assert problems(app) == [
        (
            "hotbox.rv",
            line,
            col,
            "signal 'heater_powr' is not provided by any part of the app: "
            "did you mean 'heater_power'?",
        )
    ]


def test_a_misspelled_signal_in_a_let_is_reported_inside_the_let(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "properties" / "hotbox.rv",
        "property heater_rating:\n    always (heater_power <= 100.0)",
        "let drawing = heater_powwer > 0.0\n\n"
        "property heater_rating:\n    always (heater_power <= 100.0 or drawing)\n"
        "property heater_idle:\n    always (not drawing or executed)",
    )
    line, col = place(text, "heater_powwer")
    # read at one place (its let), used by two properties: one problem
    assert problems(app) == [
        (
            "hotbox.rv",
            line,
            col,
            "signal 'heater_powwer' is not provided by any part of the app: "
            "did you mean 'heater_power'?",
        )
    ]


def test_a_misspelled_event_declaration_is_reported_where_it_is_declared(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "properties" / "hotbox.rv", "event executed\n", "event executed\nevent anomoly\n"
    )
    line, col = place(text, "anomoly")
    [(_, at_line, at_col, message)] = problems(app)
    assert (at_line, at_col) == (line, col)
    assert (
        message == "event 'anomoly' is not provided by any part of the app: did you mean 'anomaly'?"
    )


def test_an_input_with_a_default_needs_no_provider(tmp_path):
    app = copy_app(tmp_path)
    edit(
        app / "properties" / "hotbox.rv",
        "input heater_power: float\n",
        "input heater_power: float\ninput margin: float = 0.5\n",
    )
    edit(app / "properties" / "hotbox.rv", "temperature <= 41.0", "temperature <= 41.0 + margin")
    assert problems(app) == []


def test_a_signal_nothing_resembles_names_where_signals_come_from(tmp_path):
    app = copy_app(tmp_path)
    edit(app / "properties" / "hotbox.rv", "always (heater_power <=", "always (xyzzy <=")
    [(_, _, _, message)] = problems(app)
    assert message.startswith("signal 'xyzzy' is not provided by any part of the app (declare")
    assert "components.monitor.produces" in message


def test_a_misspelled_signal_in_a_veto_property_is_refused(tmp_path):
    app = copy_app(tmp_path)
    edit(
        app / "app.yaml",
        "  mode_signal: heater_mode",
        "  mode_signal: heater_mode\n  veto_properties: [heater_rating]",
    )
    assert problems(app) == []
    text = edit(
        app / "properties" / "hotbox.rv", "always (heater_power <=", "always (heatr_power <="
    )
    line, col = place(text, "heatr_power")
    [(name, at_line, at_col, message)] = problems(app)
    assert (name, at_line, at_col) == ("hotbox.rv", line, col)
    assert "'heatr_power'" in message and "did you mean 'heater_power'?" in message


def test_a_veto_property_or_mode_signal_that_does_not_exist_is_refused_in_the_manifest(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "app.yaml",
        "  mode_signal: heater_mode",
        "  mode_signal: heater_mood\n  veto_properties: [heater_ratin, timely_response]",
    )
    assert problems(app) == [
        (
            "app.yaml",
            *place(text, "heater_mood"),
            "mode signal 'heater_mood' is not a signal the app provides: "
            "did you mean 'heater_mode'?",
        ),
        (
            "app.yaml",
            *place(text, "heater_ratin"),
            "veto property 'heater_ratin' is not a property of this app: "
            "did you mean 'heater_rating'?",
        ),
    ]  # timely_response is a platform property: it exists


def test_a_type_the_reader_cannot_take_is_refused(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "properties" / "hotbox.rv", "input temperature: float", "input temperature: int"
    )
    [(_, line, col, message)] = problems(app)
    assert (line, col) == place(text, "input temperature: int")
    assert message.startswith(
        "signal 'temperature' is read as an int but probe hotbox/sensors gives it as float"
    )
    app = copy_app(tmp_path / "again")
    rules = app / "rules" / "hotbox.yaml"
    edit(rules, "mode:        {type: enum, values: [normal, boost]}", "mode:        {type: bool}")
    edit(rules, 'mode == "normal"', "mode")
    text = edit(rules, 'mode == "boost"', "not mode")
    [(_, line, col, message)] = problems(app)
    assert (line, col) == place(text, "mode:")
    assert message.startswith(
        "rule variable 'mode' is bool but components.plan.produces gives it as str"
    )


# --------------------------------------------------------------------------- rules


def test_a_misspelled_rule_variable_is_reported_at_its_declaration(tmp_path):
    app = copy_app(tmp_path)
    rules = app / "rules" / "hotbox.yaml"
    text = rules.read_text().replace("power_limit", "power_limt")
    rules.write_text(text)
    line, col = place(text, "power_limt")
    assert problems(app) == [
        (
            "hotbox.yaml",
            line,
            col,
            "rule variable 'power_limt' is neither a plan field nor a signal the app provides: "
            "did you mean 'power_limit'?",
        )
    ]


def test_a_rule_variable_no_one_provides_says_how_to_declare_plan_fields(tmp_path):
    app = copy_app(tmp_path)
    text = (app / "app.yaml").read_text()
    start = text.index("  plan:\n    component: components:HotboxPlan")
    end = text.index("  legitimate:")
    (app / "app.yaml").write_text(text[:start] + "  plan: components:HotboxPlan\n" + text[end:])
    found = problems(app)
    assert [m.split(" is ")[0] for _, _, _, m in found] == [
        "rule variable 'mode'",
        "rule variable 'power_limit'",
    ]
    assert all(
        m.endswith(
            "the app declares no plan fields: list the fields of its plans under "
            "components.plan.produces"
        )
        for _, _, _, m in found
    )


def test_effector_fields_are_plan_fields(tmp_path):
    app = copy_app(tmp_path, TURTLEBOT)
    text = (app / "app.yaml").read_text()
    start = text.index("  plan:\n    component: components:SpinPlan")
    end = text.index("  legitimate:")
    (app / "app.yaml").write_text(text[:start] + "  plan: components:SpinPlan\n" + text[end:])
    # /spin_config's fields cover the rules' variables, all but the plan's cruise speed, which
    # only the Plan's produces declares
    assert problems(app) == [("turtlebot.yaml", 8, 3, "rule variable 'cruise' is neither a plan "
                              "field nor a signal the app provides")]


# --------------------------------------------------------------------------- the manifest


@pytest.mark.parametrize(
    "old, new, needle, message",
    [
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "produces: {temperature_mean: double, temperature_trend: float}",
            "double",
            "'double' is not one of",
        ),
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "produces: {temperature_mean: float, executed: bool}",
            "executed",
            "signal 'executed': a key the loop writes itself in the trace",
        ),
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "produces: {temperature_mean: float, robustness_temperature_band: float}",
            "robustness_temperature_band",
            "signal 'robustness_temperature_band': the Trustworthiness Checker writes",
        ),
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "produces: {temperature_mean: float, lid_open: float}",
            "lid_open: float",
            "signal 'lid_open' is float here but probe hotbox/sensors gives it as bool",
        ),
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "prodces: {temperature_mean: float, temperature_trend: float}",
            "prodces",
            "unknown key 'prodces' in components.monitor",
        ),
        (
            "produces: {temperature_mean: float, temperature_trend: float}",
            "produces: {temperature mean: float}",
            "temperature mean",
            "components.monitor.produces: 'temperature mean' is not a name",
        ),
        (
            "    component: components:HotboxMonitor\n",
            "    class: components:HotboxMonitor\n",
            "class",
            "unknown key 'class' in components.monitor",
        ),
        (
            "    component: components:HotboxMonitor\n",
            "    component: components.HotboxMonitor\n",
            "components.HotboxMonitor",
            "'components.HotboxMonitor' is not module:Class",
        ),
    ],
)
def test_a_bad_produces_declaration_is_reported_at_its_place(tmp_path, old, new, needle, message):
    app = copy_app(tmp_path)
    text = edit(app / "app.yaml", old, new)
    with pytest.raises(SourceErrors) as info:
        load_manifest(app)
    found = [(e.location.line, e.location.col, e.message) for e in info.value.errors]
    line, col = place(text, needle)
    assert any((ln, c) == (line, col) and message in m for ln, c, m in found), found


def test_the_manifest_keeps_the_stage_classes_and_what_they_produce():
    manifest = load_manifest(HOTBOX)
    assert manifest.components["monitor"] == "components:HotboxMonitor"
    assert manifest.produces["monitor"] == {
        "temperature_mean": "float",
        "temperature_trend": "float",
    }
    assert manifest.produces["plan"] == {"mode": "str", "setpoint": "float", "power_limit": "float"}
    have = provided(manifest)
    assert have.trace["temperature_mean"].origin == "components.monitor.produces"
    assert have.trace["twin_residual"].type == "float" and have.trace["twin_model"].type == "json"
    assert "twin_model" in have.knowledge and have.rules["mode"].type == "str"


# --------------------------------------------------------------------------- lint and run


def test_lint_of_the_app_its_manifest_and_its_files_reports_each_problem_once(tmp_path, capsys):
    app = copy_app(tmp_path)
    edit(app / "properties" / "hotbox.rv", "always (heater_power <=", "always (heater_powr <=")
    edit(app / "properties" / "hotbox.rv", "event anomaly\n", "event anomaly\ninput broken: \n")
    rules = app / "rules" / "hotbox.yaml"
    rules.write_text(rules.read_text().replace("power_limit", "power_limt"))
    alone = lint_paths([str(app / "app.yaml")])
    assert len(alone) == 2, alone  # the .rv does not parse; the rule variable is misspelled
    assert any("power_limt" in p for p in alone)
    every_way = [
        str(app),
        str(app / "app.yaml"),
        str(app / "properties" / "hotbox.rv"),
        str(app / "rules"),
    ]
    assert lint_paths(every_way) == alone
    assert main(["lint", str(app)]) == 1
    assert capsys.readouterr().out.splitlines() == alone


def test_lint_of_an_app_and_its_model_reports_a_misread_signal_once(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["new", "plant"]) == 0  # its model names properties/plant.rv, a file
    app = tmp_path / "plant"
    assert lint_paths([str(app)]) == []
    props = app / "properties" / "plant.rv"
    text = edit(props, "once[0, 60s] anomaly)", "once[0, 60s] anomoly)")
    line, col = place(text, "anomoly")
    assert lint_paths([str(app)]) == [
        f"{props}:{line}:{col}: signal 'anomoly' is not provided by any part of the app: "
        "did you mean 'anomaly'?"
    ]
    # the model alone still says it, in its own words
    [alone] = lint_paths([str(app / "model.yaml")])
    assert alone.startswith(f"{props}:{line}:{col}: properties/plant.rv reads 'anomoly', which")


def test_rasm_run_refuses_the_app_before_anything_starts(tmp_path):
    app = copy_app(tmp_path)
    text = edit(
        app / "properties" / "hotbox.rv", "always (heater_power <=", "always (heater_powr <="
    )
    line, col = place(text, "heater_powr")
    trace = tmp_path / "trace.jsonl"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "rasm.cli",
            "run",
            str(app),
            "--clock",
            "simulated",
            "--duration",
            "2",
            "--trace",
            str(trace),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(
        f"rasm: {app / 'properties' / 'hotbox.rv'}:{line}:{col}: signal 'heater_powr' is not "
        "provided by any part of the app: did you mean 'heater_power'?\n"
    )
    assert "Traceback" not in done.stderr
    assert not trace.exists() and not (tmp_path / ".rasm").exists()


def test_the_python_api_refuses_it_too_unless_told_not_to(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    app = copy_app(tmp_path)
    edit(app / "properties" / "hotbox.rv", "always (heater_power <=", "always (heater_powr <=")
    with pytest.raises(SourceErrors, match="signal 'heater_powr' is not provided"):
        Platform(app, RunOptions(clock="simulated", knowledge="memory"))
    with pytest.raises(SourceErrors, match="signal 'heater_powr' is not provided"):
        run_app(app, seed=1, duration=1.0)
    trace = run_app(app, seed=1, duration=1.0, check_signals=False)
    assert len(trace.records) > 0


# --------------------------------------------------------------------------- for all names

_RESERVED = {
    "true",
    "false",
    "and",
    "or",
    "not",
    "abs",
    "min",
    "max",
    "prev",
    "time",
    "inf",
    "count",
    "sum",
    "avg",
    "once",
    "historically",
    "eventually",
    "always",
    "since",
    "until",
    "input",
    "event",
    "let",
    "property",
    "ms",
    "s",
}
HOTBOX_MANIFEST = load_manifest(HOTBOX)
# without the Hotbox's own property files: the test replaces them (and with them the
# robustness_<property> signals of theirs)
READABLE = {
    name: p.type
    for name, p in provided(dataclasses.replace(HOTBOX_MANIFEST, properties=[])).trace.items()
    if p.type in ("float", "int", "bool", "str") and name not in _RESERVED
}
names = st.one_of(
    st.sampled_from(sorted(READABLE)),
    st.from_regex(r"[a-z][a-z0-9_]{0,10}", fullmatch=True).filter(
        lambda n: n not in _RESERVED and not keyword.iskeyword(n)
    ),
)


def _use(name: str) -> str:
    kind = READABLE.get(name, "float")
    return {"bool": name, "str": f'{name} == "x"'}.get(kind, f"{name} > 0")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(names, min_size=1, max_size=6))
def test_every_name_not_provided_is_reported_at_each_read_and_no_provided_one(read):
    lines = [f"property p{i}:\n    always ({_use(name)})\n" for i, name in enumerate(read)]
    with tempfile.TemporaryDirectory() as folder:
        props = Path(folder) / "p.rv"
        props.write_text("".join(lines))
        manifest = dataclasses.replace(HOTBOX_MANIFEST, properties=[props], rules=[])
        found = app_problems(manifest)
    expected = [(2 * i + 2, 13, n) for i, n in enumerate(read) if n not in READABLE]
    assert [(e.location.line, e.location.col) for e in found] == [e[:2] for e in expected]
    assert all(
        e.message.startswith(f"signal '{name}' is not provided by any part of the app")
        for e, (_, _, name) in zip(found, expected, strict=True)
    )
