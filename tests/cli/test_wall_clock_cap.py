"""``RASM_MAX_WALL_SECONDS``: the cap the guides' tests put on wall-clock ``rasm run`` demos. It
cuts a wall-clock run and says so under the summary; a simulated run is left as asked; a value
that is not a positive, finite number of seconds is exit 2 with one line naming the variable."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.cli import main
from rasm.cli.commands import UsageError
from rasm.cli.live import MAX_WALL_SECONDS, _capped

HOTBOX = Path(__file__).resolve().parents[2] / "examples" / "hotbox"
seconds = st.floats(min_value=1e-3, max_value=1e6, allow_nan=False)


@given(duration=seconds, cap=seconds)
def test_the_cap_is_the_shorter_of_the_two(duration, cap):
    with pytest.MonkeyPatch.context() as env:
        env.setenv(MAX_WALL_SECONDS, repr(cap))
        assert _capped(duration) == min(duration, cap)
        env.delenv(MAX_WALL_SECONDS)
        assert _capped(duration) == duration


def not_seconds(text: str) -> bool:
    try:
        value = float(text)
    except ValueError:
        return True
    return not 0 < value < math.inf


@given(text=st.one_of(
    st.sampled_from(["0", "-1", "nan", "inf", "-inf", "1e400", "ten", "1s"]),
    st.text(min_size=1).filter(lambda t: "\x00" not in t),
).filter(not_seconds))
def test_anything_but_positive_finite_seconds_is_refused_naming_the_variable(text):
    with pytest.MonkeyPatch.context() as env:
        env.setenv(MAX_WALL_SECONDS, text)
        with pytest.raises(UsageError, match=f"^{MAX_WALL_SECONDS} must be a positive"):
            _capped(40.0)


@pytest.mark.slow
def test_a_wall_clock_run_is_cut_to_the_cap_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(MAX_WALL_SECONDS, "2")
    assert main(["run", str(HOTBOX), "--duration", "30"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("hotbox: 2 s on the wall clock, "), out
    assert out.rstrip().endswith(f"{MAX_WALL_SECONDS} cut this run to 2 s of the 30 s asked for")


def test_a_simulated_run_is_not_cut(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(MAX_WALL_SECONDS, "0.5")
    assert main(["run", str(HOTBOX), "--clock", "simulated", "--seed", "1", "--duration", "3"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("hotbox: 3 s on the simulated clock, "), out
    assert MAX_WALL_SECONDS not in out


def test_a_bad_cap_is_exit_2_with_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(MAX_WALL_SECONDS, "soon")
    assert main(["run", str(HOTBOX), "--duration", "30"]) == 2
    assert capsys.readouterr().err == (
        f"rasm: {MAX_WALL_SECONDS} must be a positive, finite number of seconds, not 'soon'\n"
    )
