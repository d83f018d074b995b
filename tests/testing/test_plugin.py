"""The pytest plugin, as a user meets it: a test file run by pytest in a fresh process."""

from __future__ import annotations

import subprocess
import sys

import pytest

from .conftest import HOTBOX, HOTBOX_PROPS

USER_TESTS = f"""
from rasm.testing import assert_properties

HOTBOX = {str(HOTBOX)!r}
PROPS = {str(HOTBOX_PROPS)!r}


def test_hotbox_holds(rasm_app):
    trace = rasm_app(HOTBOX, seed=2, duration=4)
    assert_properties(PROPS, trace)


def test_a_violation_caught_on_purpose(rasm_app):
    bad = [{{"time": 0.0, "temperature": 20.0, "heater_power": 0.0}}]
    try:
        assert_properties(PROPS, bad)
    except AssertionError:
        pass
    else:
        raise AssertionError("expected a violation")


def test_too_cold():
    assert_properties(PROPS, [{{"time": 0.0, "temperature": 30.0, "heater_power": 10.0}}])
"""


@pytest.mark.slow
def test_fixture_assertion_and_saved_failures_through_pytest(tmp_path):
    (tmp_path / "test_user.py").write_text(USER_TESTS)
    failures = tmp_path / "failures"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "--rasm-failures",
            str(failures),
            str(tmp_path / "test_user.py"),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    out = result.stdout
    assert result.returncode == 1, out + result.stderr
    assert "1 failed, 2 passed" in out
    # the failure reads like `rasm check`: the property, where, and the value that broke it
    assert "temperature_band: VIOLATED at 1 of 1 judged records" in out
    assert "temperature = 30" in out
    # both violating traces were saved in the folder given, but the summary lists only the one
    # of the test that failed
    saved = sorted(failures.glob("hotbox-*.jsonl"))
    assert len(saved) == 2
    # the section runs to the next "=====" header (pytest's short summary may quote paths too)
    section = out.split("rasm: failing examples saved", 1)[1].split("\n=", 1)[0]
    listed = [line for line in section.splitlines() if line.endswith(".jsonl")]
    assert len(listed) == 1 and '"temperature": 30.0' in open(listed[0]).read()
