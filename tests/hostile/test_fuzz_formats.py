"""Every file format, fed hostile variants of a valid file: the command exits 0, 1 or 2 with a
message, never a traceback (an unhandled exception would escape ``main()`` and fail the test).

The commands run in-process through ``main()`` (a subprocess per example would be too slow);
the regression tests in test_bad_files.py run the real command. Example counts are modest and
derandomized, so the suite stays fast and CI stable; run with a larger ``--hypothesis-seed`` or
more examples to hunt.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from rasm.cli import main

from .mutations import edited, hostile
from .support import ROOT

FUZZ = settings(
    max_examples=50,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

# a chart whose code cannot loop or compute for long, whatever edits it gets (it is run)
CHART = """\
statechart:
  name: door
  description: a door with a lock
  preamble: |
    opened = 0
    locked = False
  root state:
    name: root
    initial: closed
    states:
      - name: closed
        transitions:
          - target: open
            event: push
            guard: not locked
            action: |
              opened = opened + 1
          - target: locked_state
            event: lock
      - name: open
        on entry: |
          send('opened', count=opened)
        transitions:
          - target: closed
            event: pull
          - target: closed
            guard: after(5)
      - name: locked_state
        transitions:
          - target: closed
            event: unlock
            priority: high
"""
EVENTS = (
    '{"time": 0.5, "event": "push"}\n{"time": 1, "event": "pull", "data": {"by": "me"}}\n'
    '{"time": 2, "event": "lock"}\n{"time": 9, "event": "unlock"}\n'
)
RULES = (ROOT / "examples" / "hotbox" / "rules" / "hotbox.yaml").read_text()
PROPS = (ROOT / "examples" / "hotbox" / "properties" / "hotbox.rv").read_text()
TRACE = (
    '{"time": 0, "temperature": 36.5, "heater_power": 20.0, "anomaly": true}\n'
    '{"time": 1.5, "temperature": 37.0, "heater_power": 90.0, "executed": true}\n'
    '{"time": 7, "temperature": 41.5, "heater_power": 120.0, "anomaly": true}\n'
)


def run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str]:
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.err + out.out


def assert_no_crash(code: int, out: str) -> None:
    assert code in (0, 1, 2), out
    assert "Traceback" not in out, out


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@FUZZ
@given(text=hostile(CHART))
def test_any_chart_is_simulated_linted_and_drawn_or_refused(
    work: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    chart = work / "chart.yaml"
    chart.write_text(text, encoding="utf-8", errors="surrogatepass")
    events = work / "events.jsonl"
    events.write_text(EVENTS)
    for command in (
        ["simulate", chart, "--events", events, "--until", "20"],
        ["lint", chart],
        ["graph", chart, "--format", "dot"],
    ):
        assert_no_crash(*run(capsys, *command))


@FUZZ
@given(text=hostile(EVENTS))
def test_any_events_file_is_simulated_or_refused(
    work: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    chart = work / "door.yaml"
    chart.write_text(CHART)
    events = work / "events.jsonl"
    events.write_text(text, encoding="utf-8", errors="surrogatepass")
    code, out = run(capsys, "simulate", chart, "--events", events, "--format", "json")
    assert_no_crash(code, out)


@FUZZ
@given(text=hostile(PROPS))
def test_any_property_file_is_checked_linted_or_refused(
    work: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    props = work / "props.rv"
    props.write_text(text, encoding="utf-8", errors="surrogatepass")
    trace = work / "trace.jsonl"
    trace.write_text(TRACE)
    assert_no_crash(*run(capsys, "check", props, trace))
    assert_no_crash(*run(capsys, "lint", props))


@FUZZ
@given(text=hostile(RULES))
def test_any_rules_file_is_verified_linted_or_refused(
    work: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, text: str
) -> None:
    import rasm.rules.mus

    # an edit can make the rules nonlinear: z3 giving up is an answer too (exit 2), sooner
    monkeypatch.setattr(rasm.rules.mus, "SOLVER_TIMEOUT_MS", 500)
    rules = work / "rules.yaml"
    rules.write_text(text, encoding="utf-8", errors="surrogatepass")
    assert_no_crash(*run(capsys, "verify-rules", rules))
    assert_no_crash(*run(capsys, "lint", rules))


@pytest.fixture(scope="module")
def app(work: Path) -> Path:
    folder = work / "hotbox"
    shutil.copytree(ROOT / "examples" / "hotbox", folder)
    return folder


@FUZZ
@given(text=hostile((ROOT / "examples" / "hotbox" / "app.yaml").read_text()))
def test_any_app_manifest_is_linted_or_refused(
    app: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    (app / "app.yaml").write_text(text, encoding="utf-8", errors="surrogatepass")
    assert_no_crash(*run(capsys, "lint", app / "app.yaml"))


@settings(FUZZ, max_examples=15)
@given(text=edited((ROOT / "examples" / "hotbox" / "app.yaml").read_text(), 2))
def test_any_app_manifest_runs_or_is_refused(
    app: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    (app / "app.yaml").write_text(text, encoding="utf-8", errors="surrogatepass")
    code, out = run(
        capsys, "run", app, "--clock", "simulated", "--duration", "2", "--seed", "1"
    )
    assert code in (0, 1, 2), out
    assert "Traceback" not in out.split("stage failed")[0], out  # stage failures log theirs
