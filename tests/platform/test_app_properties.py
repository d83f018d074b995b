"""The properties a run checks: the platform's own (as the app sets them: limits, or off) and
the app's, each name defined once."""

from __future__ import annotations

import shutil

import pytest

from rasm import Anomaly, Plan, Platform, RunOptions
from rasm.cli import main
from rasm.errors import PlatformError
from rasm.platform.app_properties import LIMITS, compile_app_properties, platform_specifications
from rasm.platform.manifest import SCHEMA, load_manifest
from rasm.properties.printer import unparse
from rasm.resources import data_dir

from .conftest import HOTBOX


def hotbox_with(folder, extra_rv):
    """The Hotbox with one more property file, ``properties/extra.rv``."""
    shutil.copytree(HOTBOX, folder, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    (folder / "properties" / "extra.rv").write_text(extra_rv, encoding="utf-8")
    app = folder / "app.yaml"
    text = app.read_text(encoding="utf-8")
    app.write_text(
        text.replace(
            "  - properties/hotbox.rv\n", "  - properties/hotbox.rv\n  - properties/extra.rv\n"
        ),
        encoding="utf-8",
    )
    return load_manifest(folder)


def test_the_platforms_properties_come_first_then_the_apps_in_their_order(tmp_path):
    m = hotbox_with(
        tmp_path / "app", "input temperature: float\nproperty warm:\n  always (temperature > 0.0)\n"
    )
    monitors = compile_app_properties(m)
    own = sorted(data_dir("properties").glob("*.rv"))
    assert len(monitors) == len(own) + 2
    assert "stage_order" in monitors[len(own) - 1].properties  # maple_k.rv, the last of its own
    assert "temperature_band" in monitors[-2].properties and list(monitors[-1].properties) == [
        "warm"
    ]


def test_a_property_name_the_app_defines_twice_is_refused_naming_both_files(tmp_path):
    m = hotbox_with(
        tmp_path / "app",
        "input temperature: float\nproperty temperature_band:\n  always (temperature > 0.0)\n",
    )
    with pytest.raises(PlatformError) as caught:
        compile_app_properties(m)
    message = str(caught.value)
    assert "'temperature_band'" in message and "extra.rv" in message and "hotbox.rv" in message


def test_an_app_property_named_like_one_of_the_platforms_is_refused(tmp_path):
    m = hotbox_with(
        tmp_path / "app", "event executed\nproperty loop_alive:\n  always (not executed)\n"
    )
    with pytest.raises(
        PlatformError, match=r"'loop_alive' of .*extra\.rv is already defined in .*maple_k\.rv"
    ):
        compile_app_properties(m)


# ---------------------------------------------------------------- platform_properties in app.yaml


def hotbox_setting(folder, setting: str):
    """The Hotbox with ``setting`` (YAML lines) as its ``platform_properties:``."""
    shutil.copytree(HOTBOX, folder, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    app = folder / "app.yaml"
    if setting:
        app.write_text(app.read_text(encoding="utf-8") + "platform_properties:\n" + setting,
                       encoding="utf-8")
    return folder


class PickerEveryIteration:
    """A busy aisle: a picker steps in front of the robot at every iteration."""

    def analyse(self, ctx):
        return Anomaly("a picker ahead", {"want": "normal"})


class SlowDown:
    def plan(self, ctx):
        return Plan({"mode": "normal", "setpoint": 37.0, "power_limit": 50.0})


def busy_run(folder):
    return Platform(load_manifest(folder), RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        components={"analyse": PickerEveryIteration(), "plan": SlowDown()},
    )).run(3.2)


def test_a_busy_aisle_oscillates_by_default_and_passes_with_the_apps_own_limit(tmp_path):
    # the robot rightly slows for each of six pickers in three seconds: more than the five
    # adaptations in ten seconds no_oscillation allows by default
    default = busy_run(hotbox_setting(tmp_path / "default", ""))
    assert default.stats.executed >= 6
    assert default.verdicts["no_oscillation"] == "violated" and not default.ok
    tuned = busy_run(hotbox_setting(tmp_path / "tuned", "  no_oscillation: {max_actions: 8}\n"))
    assert tuned.verdicts["no_oscillation"] == "satisfied"
    # the window is a limit too: two actions a second, every half second, are not three
    close = busy_run(hotbox_setting(tmp_path / "close", "  no_oscillation: {max_actions: 2}\n"))
    assert close.verdicts["no_oscillation"] == "violated"
    narrow = busy_run(hotbox_setting(
        tmp_path / "narrow", "  no_oscillation: {max_actions: 2, window: 0.9}\n"))
    assert narrow.verdicts["no_oscillation"] == "satisfied"


def test_a_platform_property_turned_off_is_not_checked_and_the_summary_says_so(tmp_path, capsys,
                                                                             monkeypatch):
    folder = hotbox_setting(tmp_path / "app", "  no_oscillation: off\n  prompt_planning: off\n")
    summary = busy_run(folder)
    assert "no_oscillation" not in summary.verdicts and "prompt_planning" not in summary.verdicts
    assert summary.off == ("no_oscillation", "prompt_planning")
    assert summary.verdicts["stage_order"] == "satisfied"  # the guarantees are checked
    monkeypatch.chdir(tmp_path)
    main(["run", str(folder), "--clock", "simulated", "--duration", "3"])
    out = capsys.readouterr().out
    assert "not checked (off in app.yaml): no_oscillation, prompt_planning" in out


def test_limits_rewrite_exactly_the_window_or_the_number_they_name():
    specs = platform_specifications(
        {"timely_response": {"within": 3.5}, "no_oscillation": {"max_actions": 9, "window": 30},
         "loop_alive": {"within": 12}, "prompt_planning": None},
        stage_budget=2.5,
    )
    formulas = {p.name: unparse(p.formula) for spec in specs for p in spec.properties}
    assert formulas["timely_response"] == "anomaly -> eventually[0, 3.5] (executed or rejected)"
    assert formulas["no_oscillation"] == "count[0, 30](executed) <= 9"
    assert formulas["loop_alive"] == 'once[0, 12] stage == "monitor"'
    assert formulas["stage_budget"] == "duration <= 2.5"  # the app's loop.stage_budget
    assert "prompt_planning" not in formulas
    # every limit of the table sits in exactly one place of its property, whatever its value
    for name, limits in LIMITS.items():
        platform_specifications({name: {limit: 1 for limit in limits}})
    # the defaults are the numbers written in properties/*.rv
    plain = {p.name: unparse(p.formula) for s in platform_specifications() for p in s.properties}
    assert plain["no_oscillation"] == "count[0, 10](executed) <= 5"
    assert plain["prompt_planning"] == "anomaly -> eventually[0, 0.5] planned"


def test_the_schema_names_every_tunable_platform_property_and_each_limit():
    written = SCHEMA["properties"]["platform_properties"]["properties"]
    assert {name: sorted(spec["properties"]) for name, spec in written.items()} == {
        name: sorted(limits) for name, limits in LIMITS.items()
    }


def test_platform_properties_are_named_by_their_place_in_rasm_not_the_install_path(tmp_path):
    m = load_manifest(HOTBOX)
    sources = [monitor.spec.source for monitor in compile_app_properties(m)]
    assert sources[:2] == ["rasm:properties/adaptation.rv", "rasm:properties/maple_k.rv"]
    prop = compile_app_properties(m)[0].spec.properties[0]
    assert str(prop.location).startswith("rasm:properties/adaptation.rv:")


@pytest.mark.parametrize(
    ("setting", "where", "message"),
    [
        ("  no_oscilation: off\n", "2:3", "unknown key 'no_oscilation' in platform_properties "
         "(the platform properties an app may tune or turn off: timely_response, "),
        ("  stage_order: off\n", "2:3", "unknown key 'stage_order' in platform_properties"),
        ("  no_oscillation: of\n", "2:19", "platform_properties.no_oscillation: 'of' is "
         "neither off nor a mapping of its limits"),
        ("  no_oscillation: 8\n", "2:19", "platform_properties.no_oscillation: 8 is neither "
         "off nor a mapping of its limits"),
        ("  no_oscillation: {max: 8}\n", "2:20", "unknown key 'max' in "
         "platform_properties.no_oscillation"),
        ("  no_oscillation: {max_actions: 2.5}\n", "2:33", "max_actions: 2.5 is not of type "
         "'integer'"),
        ("  timely_response: {within: 0}\n", "2:29", "within: 0 is less than or equal to "
         "the minimum of 0"),
        ("  timely_response: {within: .inf}\n", "2:29", "must be a finite number"),
    ],
)
def test_bad_settings_are_refused_at_their_place(tmp_path, capsys, setting, where, message):
    folder = hotbox_setting(tmp_path / "app", setting)
    assert main(["lint", str(folder / "app.yaml")]) == 1
    out = capsys.readouterr().out
    line = len((HOTBOX / "app.yaml").read_text().splitlines()) + int(where.split(":")[0])
    assert f"app.yaml:{line}:{where.split(':')[1]}: " in out and message in out, out
    assert main(["run", str(folder), "--clock", "simulated", "--duration", "1"]) == 2
    assert message in capsys.readouterr().err


def test_a_veto_property_turned_off_is_refused(tmp_path, capsys):
    folder = hotbox_setting(tmp_path / "app", "  no_oscillation: off\n")
    app = folder / "app.yaml"
    app.write_text(app.read_text().replace(
        "trustworthiness:\n", "trustworthiness:\n  veto_properties: [no_oscillation]\n"))
    assert main(["lint", str(app)]) == 1
    out = capsys.readouterr().out
    line = len((HOTBOX / "app.yaml").read_text().splitlines()) + 3
    assert (f"app.yaml:{line}:19: platform property 'no_oscillation' is off but vetoes actions"
            in out), out
    assert main(["run", str(folder), "--clock", "simulated", "--duration", "1"]) == 2
    assert "is off but vetoes actions" in capsys.readouterr().err
