"""Model lint: every problem at its file, line and column; the example models are clean."""

from __future__ import annotations

from pathlib import Path

import pytest

from rasm.workflow import lint_model, load_model
from rasm.workflow.model import SCHEMA

from .helpers import HOTBOX_MODEL, ROOT, position

BASE = HOTBOX_MODEL.read_text(encoding="utf-8")


def lint(tmp_path: Path, text: str) -> list[tuple[int, int, str]]:
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    errors = lint_model(path)
    assert all(e.location.file == str(path) for e in errors)
    return [(e.location.line, e.location.col, e.message) for e in errors]


def one(tmp_path: Path, text: str) -> tuple[int, int, str]:
    errors = lint(tmp_path, text)
    assert len(errors) == 1, errors
    return errors[0]


def test_the_example_models_lint_clean() -> None:
    models = sorted((ROOT / "examples" / "models").glob("*.yaml"))
    assert len(models) >= 2
    for model in models:
        assert lint_model(model) == [], model


def test_the_schema_is_a_json_schema_with_the_recognising_key() -> None:
    assert "architecture" in SCHEMA["required"]
    assert {
        "components",
        "compute_units",
        "deployment",
        "communication",
        "trustworthiness",
        "interface",
        "messages",
    } <= set(SCHEMA["properties"])


def test_unknown_key_is_reported_at_the_key(tmp_path: Path) -> None:
    text = BASE.replace("    os: linux\n    cpus: 1\n", "    os: linux\n    gpus: 1\n", 1)
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "gpus")
    assert "unknown key 'gpus'" in message


def test_bad_enum_value_is_reported_at_the_value(tmp_path: Path) -> None:
    text = BASE.replace("arch: arm64", "arch: sparc")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "sparc")
    assert "sparc" in message


def test_dangling_message_type(tmp_path: Path) -> None:
    text = BASE.replace(
        "readings: {direction: out, message: HotboxSensors}",
        "readings: {direction: out, message: HotboxSensor}",
    )
    errors = lint(tmp_path, text)
    where = position(text, "HotboxSensor}")
    assert (
        *where,
        "port sensors.readings: unknown message type 'HotboxSensor' "
        "(known: HeaterSettings, HotboxSensors)",
    ) in errors
    # the subscriber's type no longer matches what the publisher declares
    assert any(
        "expects HotboxSensors but sensors.readings publishes HotboxSensor" in e[2] for e in errors
    )


def test_dangling_compute_unit_in_deployment(tmp_path: Path) -> None:
    text = BASE.replace("  plan: edge\n", "  plan: cloud\n")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "cloud")
    assert "'plan' is deployed on an unknown compute unit 'cloud'" in message


def test_dangling_component_in_deployment(tmp_path: Path) -> None:
    text = BASE.replace("  execute: edge\n", "  execute: edge\n  planner: edge\n")
    line, col, message = one(tmp_path, text)
    assert (line, col) == (position(text, "planner: edge")[0], 12)
    assert "unknown component 'planner'" in message


def test_dangling_port_in_the_matrix(tmp_path: Path) -> None:
    text = BASE.replace("subscribers: [monitor.readings]", "subscribers: [monitor.reading]")
    errors = lint(tmp_path, text)
    at = position(text, "monitor.reading]")
    assert (
        *at,
        "topic hotbox/sensors: component 'monitor' has no port 'reading' (it has readings)",
    ) in errors
    # and the port it meant to connect is now left without a peer
    port = position(text, "readings: {direction: in")
    assert any((e[0], e[1]) == port and "has no peer" in e[2] for e in errors)


def test_dangling_runs_on(tmp_path: Path) -> None:
    text = BASE.replace(
        "- file: rules/hotbox.yaml\n      runs_on: edge",
        "- file: rules/hotbox.yaml\n      runs_on: cloud",
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "cloud")
    assert "rules/hotbox.yaml runs on an unknown compute unit 'cloud'" in message


def test_port_with_no_peer(tmp_path: Path) -> None:
    text = BASE.replace(
        "      settings: {direction: in, message: HeaterSettings}\n",
        "      settings: {direction: in, message: HeaterSettings}\n"
        "      status: {direction: out, message: HotboxSensors}\n",
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "status:")
    assert message.startswith("port heater.status has no peer")


def test_publisher_subscriber_type_mismatch(tmp_path: Path) -> None:
    text = BASE.replace(
        "settings: {direction: in, message: HeaterSettings}",
        "settings: {direction: in, message: HotboxSensors}",
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "heater.settings]")
    assert message == (
        "topic hotbox/heater: heater.settings expects HotboxSensors but "
        "execute.settings publishes HeaterSettings"
    )


def test_direction_mismatch(tmp_path: Path) -> None:
    text = BASE.replace(
        "settings: {direction: out, message: HeaterSettings}",
        "settings: {direction: in, message: HeaterSettings}",
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "execute.settings")
    assert "publisher execute.settings is an 'in' port" in message


def test_component_on_no_compute_unit(tmp_path: Path) -> None:
    text = BASE.replace("  heater: box\n", "")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "heater:")
    assert message.startswith("component 'heater' is deployed on no compute unit")


def test_unit_whose_transports_cannot_reach_a_peer(tmp_path: Path) -> None:
    text = BASE.replace(
        "    memory_mb: 4096\n    transports: [local, mqtt]",
        "    memory_mb: 4096\n    transports: [local]",
    )
    errors = lint(tmp_path, text)
    assert [(e[0], e[1]) for e in errors] == [
        position(text, "monitor.readings]"),
        position(text, "heater.settings]"),
    ]
    assert errors[0][2] == (
        "compute unit 'edge' (transports: local) cannot reach 'sensors' on "
        "'box' over mqtt (topic hotbox/sensors)"
    )


def test_local_protocol_cannot_cross_units(tmp_path: Path) -> None:
    text = BASE.replace("    transports: [mqtt]\n", "    transports: [local, mqtt]\n").replace(
        "    protocol: mqtt\n    qos: 1", "    protocol: local\n    qos: 1"
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "monitor.readings]")
    assert "over local (an in-process bus); use protocol: mqtt" in message


def test_crossing_units_needs_a_broker(tmp_path: Path) -> None:
    text = BASE.replace("transport: mqtt://localhost:1883", "transport: local")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "local\n  knowledge")
    assert "interface.transport is 'local'" in message


@pytest.mark.parametrize("stage", ["analyse", "plan", "legitimate"])
def test_loop_missing_a_stage(tmp_path: Path, stage: str) -> None:
    text = BASE.replace(f"  {stage}: {{role: {stage}}}\n", "").replace(f"  {stage}: edge\n", "")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "components:")
    assert message == f"the MAPLE-K loop has no {stage} stage (add a component with role: {stage})"


def test_loop_repeating_a_stage(tmp_path: Path) -> None:
    text = BASE.replace("  plan: {role: plan}\n", "  plan: {role: plan}\n  plan2: {role: plan}\n")
    text = text.replace("  plan: edge\n", "  plan: edge\n  plan2: edge\n")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "plan2:")
    assert "repeats the plan stage" in message


def test_loop_split_over_units(tmp_path: Path) -> None:
    text = BASE.replace("  plan: edge\n", "  plan: box\n")
    line, col, message = one(tmp_path, text)
    assert (line, col) == (position(text, "plan: box")[0], 9)
    assert "the plan stage 'plan' is on 'box' but the loop runs on 'edge'" in message


def test_property_reading_a_signal_nobody_produces(tmp_path: Path) -> None:
    text = BASE.replace("always (heater_power <= 100.0)", "always (heater_current <= 100.0)")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "heater_current")
    assert message.startswith("properties/hotbox.rv reads 'heater_current', which no component")


def test_property_in_a_file_beside_the_model(tmp_path: Path) -> None:
    text = BASE.replace(
        "    - file: properties/hotbox.rv\n      runs_on: edge\n      text: |",
        "    - file: props.rv\n      runs_on: edge\n      unused: |",
    )
    start = text.index("      unused: |")
    end = text.index("  rules:")
    text = text[:start] + text[end:]
    props = tmp_path / "props.rv"
    props.write_text("input x: float\nproperty p:\n    always (x > 0)\n")
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    [error] = lint_model(path)
    assert error.location.file == str(props)
    assert (error.location.line, error.location.col) == (3, 13)
    assert "reads 'x'" in error.message


def test_bad_property_text_is_reported_inside_the_model(tmp_path: Path) -> None:
    text = BASE.replace("always (heater_power <= 100.0)", "always (heater_power <= )")
    line, col, message = one(tmp_path, text)
    assert line == position(text, "always (heater_power <= )")[0]


def test_bad_rules_text_is_reported_inside_the_model(tmp_path: Path) -> None:
    text = BASE.replace("require: power_limit <= 100", "require: power_limt <= 100")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "power_limt")


def test_not_a_model(tmp_path: Path) -> None:
    errors = lint(tmp_path, "components: {}\n")
    assert errors == [
        (1, 1, "an architecture model is a mapping with a top-level 'architecture: NAME'")
    ]


def test_yaml_syntax_error_has_a_position(tmp_path: Path) -> None:
    line, col, message = one(tmp_path, "architecture: x\ncomponents: [\n")
    assert line >= 2 and "YAML syntax error" in message


def test_load_model_reads_every_section() -> None:
    model = load_model(HOTBOX_MODEL)
    assert model.name == "hotbox"
    assert model.managing_unit == "edge"
    assert {c.name for c in model.components_on("box")} == {"sensors", "heater"}
    assert [link.topic for link in model.links] == ["hotbox/sensors", "hotbox/heater"]
    assert [(c.kind, c.runs_on) for c in model.checks] == [
        ("properties", "edge"),
        ("rules", "edge"),
    ]


def test_two_probe_messages_giving_one_signal_two_types(tmp_path: Path) -> None:
    text = BASE.replace(
        "      mode: {type: str}\n      setpoint: {type: float, min: 0, max: 100}\n"
        "      power_limit",
        "      mode: {type: str}\n      setpoint: {type: float, min: 0, max: 100}\n"
        "      power_limit",
    )
    text = text.replace(
        "  HeaterSettings:\n",
        "  LidSensor:\n    fields:\n      lid_open: {type: float}\n  HeaterSettings:\n",
    )
    text = text.replace(
        "      readings: {direction: out, message: HotboxSensors}\n",
        "      readings: {direction: out, message: HotboxSensors}\n"
        "      lid: {direction: out, message: LidSensor}\n",
    ).replace(
        "      readings: {direction: in, message: HotboxSensors}\n",
        "      readings: {direction: in, message: HotboxSensors}\n"
        "      lid: {direction: in, message: LidSensor}\n",
    )
    text = text.replace(
        "\ntrustworthiness:",
        "  - {topic: hotbox/lid, publisher: sensors.lid, subscribers: [monitor.lid],"
        " protocol: mqtt}\n\ntrustworthiness:",
    )
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "lid_open: {type: float}")
    assert message == (
        "field 'lid_open' of LidSensor is float but HotboxSensors's is bool: "
        "both reach knowledge as 'lid_open'"
    )


def test_rule_variable_nobody_produces_is_reported_inside_the_model(tmp_path: Path) -> None:
    rules = BASE.index("  rules:\n")
    text = BASE[:rules] + BASE[rules:].replace("power_limit", "power_limt")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "power_limt")
    assert message == (
        "rules/hotbox.yaml declares rule variable 'power_limt', which no component produces "
        "(did you mean 'power_limit'?)"
    )


def test_a_misspelled_signal_names_the_closest_produced_one(tmp_path: Path) -> None:
    text = BASE.replace("always (heater_power <= 100.0)", "always (heater_powr <= 100.0)")
    line, col, message = one(tmp_path, text)
    assert (line, col) == position(text, "heater_powr")
    assert message.endswith("which no component produces (did you mean 'heater_power'?)")
