"""rasm new: the skeleton lints clean, runs, passes its own tests, and regeneration keeps code."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rasm.cli import main
from rasm.lint import lint_paths
from rasm.platform.manifest import load_manifest
from rasm.workflow import GenerateError, lint_model, new_app
from rasm.workflow.regions import RegionError, merge, parse_regions

from .helpers import HOTBOX_MODEL, ROOT, forget_apps, position


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)  # rasm run keeps its state under ./.rasm
    forget_apps()
    yield
    forget_apps()


def app_lint(app: Path) -> list[str]:
    """Problems in the app's manifest, properties and rules, and in its model."""
    manifest = load_manifest(app)
    paths = [str(manifest.file), *map(str, manifest.properties), *map(str, manifest.rules)]
    return lint_paths(paths) + [str(e) for e in lint_model(app / "model.yaml")]


@pytest.mark.slow
def test_new_without_a_model_writes_a_starter_that_lints_runs_and_passes_its_tests(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["new", "plant"]) == 0
    app = tmp_path / "plant"
    out = capsys.readouterr().out
    for name in (
        "model.yaml",
        "app.yaml",
        "components.py",
        "messages.py",
        "README.md",
        "properties/plant.rv",
        "rules/plant.yaml",
        "tests/test_plant.py",
    ):
        assert (app / name).is_file(), name
        if name != "model.yaml":
            assert f"wrote {app / name}" in out or f"wrote plant/{name}" in out
    assert app_lint(app) == []
    assert main(["run", str(app), "--clock", "simulated", "--duration", "2"]) == 0
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"],
        cwd=app,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 passed" in done.stdout


@pytest.mark.slow
def test_the_generated_tests_fail_on_a_property_that_is_never_judged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A property reading a signal nothing sends passes no generated test: it is not judged."""
    assert main(["new", "plant"]) == 0
    app = tmp_path / "plant"
    props = app / "properties" / "plant.rv"
    props.write_text(props.read_text() + "\nproperty typo:\n    always (levle <= 1.0)\n")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests",
         "-k", "every_property"],
        cwd=app,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert "levle" in done.stdout


def test_new_from_the_hotbox_model(tmp_path: Path) -> None:
    assert main(["new", "hb", "--from", str(HOTBOX_MODEL)]) == 0
    app = tmp_path / "hb"
    assert app_lint(app) == []
    text = (app / "components.py").read_text()
    for cls in (
        "class Monitor:",
        "class Analyse:",
        "class PlanComponent:",
        "class Legitimate:",
        "class Execute:",
        "class Sensors:",
        "class Heater:",
        "class Simulator:",
    ):
        assert cls in text
    assert "# >>> rasm:user PlanComponent.plan" in text
    assert "def on_settings(self, message: Any, time: float)" in text
    manifest = load_manifest(app)
    assert [p.topic for p in manifest.probes] == ["hotbox/sensors"]
    assert set(manifest.probes[0].signals) == {
        "temperature",
        "lid_open",
        "heater_power",
        "heater_mode",
        "setpoint",
    }
    assert manifest.effectors["heater"].topic == "hotbox/heater"
    assert manifest.mode_signal == "heater_mode"
    # the model's property and rule texts became the app's files
    assert "property temperature_band" in (app / "properties/hotbox.rv").read_text()
    assert "safe_setpoint" in (app / "rules/hotbox.yaml").read_text()
    # placeholders report 0 degrees: the run works, and the band property says the sensors
    # still have to be written
    assert main(["run", str(app), "--clock", "simulated", "--duration", "2"]) == 1


def test_generated_code_is_ruff_clean(tmp_path: Path) -> None:
    ruff = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    if not Path(ruff).exists():
        pytest.skip("ruff is not installed")
    new_app(tmp_path / "tb", ROOT / "examples" / "models" / "turtlebot.yaml")
    new_app(tmp_path / "plant")
    # as an engineer's project outside the rasm repository sees it (rasm is third-party)
    done = subprocess.run(
        [
            ruff,
            "check",
            "--isolated",
            "--no-cache",
            "--line-length",
            "100",
            "--select",
            "E,F,W,I,B,UP",
            "tb",
            "plant",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout


ENGINEER_PLAN = """\
        want = ctx.anomaly.data.get("want", "normal")
        return Plan({"mode": want, "setpoint": 37.5, "power_limit": 60.0})
"""


def test_regeneration_keeps_the_engineers_code_and_reports_what_it_cannot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    app = tmp_path / "hb"
    new_app(app, HOTBOX_MODEL)
    components = app / "components.py"
    text = components.read_text()
    plan_end = "        # <<< rasm:user PlanComponent.plan"
    heater_end = "        # <<< rasm:user Heater.on_settings"
    text = text.replace("        return None  # placeholder\n" + plan_end, ENGINEER_PLAN + plan_end)
    text = text.replace(
        "        pass  # placeholder\n" + heater_end,
        "        self.settings = message\n" + heater_end,
    )
    text = text.replace("# >>> rasm:user imports\n", "# >>> rasm:user imports\nimport math\n")
    components.write_text(text)
    (app / "properties/hotbox.rv").write_text(
        "# mine\nevent anomaly\nproperty p:\n    always (anomaly or not anomaly)\n"
    )
    # the model changes: the heater is now called boiler, and a new probe appears
    model = (
        HOTBOX_MODEL.read_text()
        .replace("heater:", "boiler:")
        .replace("[heater.settings]", "[boiler.settings]")
        .replace("  heater: box", "  boiler: box")
    )
    changed = tmp_path / "changed.yaml"
    changed.write_text(model)
    capsys.readouterr()
    assert main(["new", str(app), "--from", str(changed)]) == 0
    captured = capsys.readouterr()
    regenerated = components.read_text()
    assert ENGINEER_PLAN in regenerated
    assert "import math" in regenerated
    assert "class Boiler:" in regenerated and "class Heater:" not in regenerated
    assert "self.settings = message" not in regenerated
    assert "region Heater.on_settings could not be kept" in captured.err
    orphans = (app / ".rasm-orphans" / "components.py.txt").read_text()
    assert "self.settings = message" in orphans
    # the engineer's own files are left alone
    assert (app / "properties/hotbox.rv").read_text().startswith("# mine")
    assert f"kept  {app / 'properties/hotbox.rv'}" in captured.out
    assert (app / "model.yaml").read_text() == model
    assert app_lint(app) == []
    # regenerating again with no change changes nothing
    before = {p: p.read_text() for p in app.rglob("*") if p.is_file()}
    new_app(app)
    assert {p: p.read_text() for p in app.rglob("*") if p.is_file()} == before


def test_an_invalid_model_is_refused_with_positions_and_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = HOTBOX_MODEL.read_text().replace("  plan: {role: plan}\n", "")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    assert main(["new", "x", "--from", str(bad)]) == 2
    line, col = position(text, "components:")
    assert f"{bad}:{line}:{col}: the MAPLE-K loop has no plan stage" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_new_refuses_a_folder_it_did_not_generate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    assert main(["new", "mine"]) == 2
    assert "was not generated by rasm new" in capsys.readouterr().err
    with pytest.raises(GenerateError):
        new_app(tmp_path / "mine")


def test_regions_parse_and_merge() -> None:
    old = (
        "a\n# >>> rasm:user x\nmine\n# <<< rasm:user x\n"
        "# >>> rasm:user gone\nlost\n# <<< rasm:user gone\n"
    )
    fresh = "A\n# >>> rasm:user x\ndefault  # placeholder\n# <<< rasm:user x\n"
    text, orphans = merge(fresh, old)
    assert text == "A\n# >>> rasm:user x\nmine\n# <<< rasm:user x\n"
    assert [(o.id, o.body, o.written) for o in orphans] == [("gone", ("lost",), True)]
    assert not parse_regions(fresh)["x"].written
    for broken in (
        "# >>> rasm:user a\n",
        "# <<< rasm:user a\n",
        "# >>> rasm:user a\n# >>> rasm:user b\n",
    ):
        with pytest.raises(RegionError):
            parse_regions(broken)


def test_regeneration_refuses_broken_markers(tmp_path: Path) -> None:
    app = tmp_path / "plant"
    new_app(app)
    components = app / "components.py"
    components.write_text(components.read_text().replace("# <<< rasm:user Plan", "# <<< oops", 1))
    (app / "model.yaml").write_text((app / "model.yaml").read_text().replace("plant/", "p/"))
    before = {p: p.read_text() for p in app.rglob("*") if p.is_file()}
    with pytest.raises(GenerateError, match="components.py"):
        new_app(app)
    assert {p: p.read_text() for p in app.rglob("*") if p.is_file()} == before


def test_the_generated_tests_use_the_running_rasm() -> None:
    assert os.path.isfile(ROOT / "rasm" / "workflow" / "templates" / "app" / "test_app.py.j2")


def test_the_generated_readme_regenerates_from_inside_the_app_and_nesting_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["new", "hb", "--from", str(HOTBOX_MODEL)]) == 0
    app = tmp_path / "hb"
    readme = (app / "README.md").read_text()
    assert "$ rasm new .  " in readme
    for name in ("README.md", "components.py", "app.yaml"):  # every file says the same
        assert "--from model.yaml" not in (app / name).read_text(), name
    # as the README says, from the app folder: regenerated in place, the user's code kept
    components = app / "components.py"
    components.write_text(
        components.read_text().replace(
            "# >>> rasm:user imports\n", "# >>> rasm:user imports\nMARK = 1\n"
        )
    )
    monkeypatch.chdir(app)
    capsys.readouterr()
    assert main(["new", "."]) == 0
    assert "MARK = 1" in components.read_text()
    # what the old README said, typed in the app folder: refused, nothing nested
    assert main(["new", "hb", "--from", "model.yaml"]) == 2
    err = capsys.readouterr().err
    assert "is an app folder" in err and "rasm new ." in err and "Traceback" not in err
    assert not (app / "hb").exists()
    with pytest.raises(GenerateError, match="will not create the app hb inside it"):
        new_app("hb")
