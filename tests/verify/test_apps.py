"""rasm verify APP: the charts an app runs, bound together, explored completely; the checks
the platform always makes; planted bugs in replacement charts found with a counterexample."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rasm.cli import main
from rasm.resources import platform_chart
from rasm.verify.app import APP_CHECKS, verify_app

ROOT = Path(__file__).resolve().parents[2]


def test_the_hotbox_verifies_completely(capsys):
    assert main(["verify", str(ROOT / "examples" / "hotbox"), "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"] == "satisfied" and report["complete"]
    assert [p["name"] for p in report["properties"]] == list(APP_CHECKS)
    assert {p["verdict"] for p in report["properties"]} == {"satisfied"}
    # the orchestrator was in every stage, and back in idle
    states = set().union(*map(set, report["reachable"]))
    for stage in ("monitoring", "analysing", "planning", "legitimating", "executing", "idle"):
        assert f"ao:{stage}" in states


@pytest.mark.slow
def test_the_turtlebot_verifies_completely():
    result = verify_app(ROOT / "examples" / "turtlebot")
    assert (result.verdict, result.complete) == ("satisfied", True), result.problems
    states = set().union(*map(set, result.reachable))
    # its analyse chart and its modes chart were explored with it
    assert {"analyse:occluded", "analyse:recovering", "modes:spin", "modes:blocked"} <= states


def _fallback_app(tmp_path: Path, chart: str) -> Path:
    app = tmp_path / "hotbox"
    shutil.copytree(ROOT / "examples" / "hotbox", app)
    (app / "my_fallback.yaml").write_text(chart)
    manifest = app / "app.fallback.yaml"
    manifest.write_text(
        manifest.read_text() + "statecharts:\n  fallback: my_fallback.yaml\n"
    )
    return manifest


def test_a_fallback_chart_that_hands_back_on_a_trigger_is_caught(tmp_path):
    # the planted bug: a trigger while recovering leaves recovering (the interface holds) but
    # for nominal, so the fallback does not hold while the trigger does
    chart = platform_chart("fallback").read_text()
    planted = chart.replace(
        """          - name: recovering
            transitions:
              - target: fallback
                event: trigger""",
        """          - name: recovering
            transitions:
              - target: nominal
                event: trigger""",
    )
    assert planted != chart
    result = verify_app(_fallback_app(tmp_path, planted))
    verdicts = {p.name: p for p in result.properties}
    assert verdicts["fallback_engages"].verdict == "violated"
    events = [line.get("event") for line in verdicts["fallback_engages"].counterexample.events()]
    # engaged, cleared, then triggered again while recovering
    assert events.count("veto violated") >= 1 and "veto vouches" in events
    assert events[-1] in ("veto violated", "managed system lost", "tick")
    assert result.exit_code == 1


def test_an_app_rasm_run_refuses_is_refused_at_its_place(tmp_path, capsys):
    app = tmp_path / "hotbox"
    shutil.copytree(ROOT / "examples" / "hotbox", app)
    manifest = app / "app.yaml"
    manifest.write_text(manifest.read_text().replace("mode_signal: heater_mode",
                                                     "mode_signal: heater_mood"))
    assert main(["verify", str(app)]) == 2
    err = capsys.readouterr().err
    assert "app.yaml:" in err and "heater_mood" in err and "Traceback" not in err


def test_env_and_properties_are_for_one_chart(tmp_path, capsys):
    assert main(["verify", str(ROOT / "examples" / "hotbox"), "--env", "x.yaml"]) == 2
    assert "--env and --properties apply to one chart" in capsys.readouterr().err
