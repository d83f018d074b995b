"""in_mode("state") reads the signal mode_<state> the managed system's modes chart writes."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.errors import SourceError, SourceErrors
from rasm.properties import compile_properties

SPEC = 'property p:\n    always (in_mode("arrived") -> not executed)\n'


@given(st.lists(st.tuples(st.booleans(), st.booleans()), min_size=1, max_size=30))
def test_in_mode_is_the_mode_signal(records):
    """For any trace, in_mode("arrived") gives exactly what the signal mode_arrived gives."""
    trace = [
        (float(i), {"mode_arrived": arrived, "executed": executed})
        for i, (arrived, executed) in enumerate(records)
    ]
    with_call = compile_properties(SPEC).run(trace)
    plain = compile_properties(SPEC.replace('in_mode("arrived")', "mode_arrived")).run(trace)
    assert [r.values for r in with_call] == [r.values for r in plain]


@pytest.mark.parametrize("call", ["in_mode(arrived)", 'in_mode("a b")', "in_mode()",
                                  'in_mode("a", "b")'])
def test_in_mode_takes_one_state_name(call):
    with pytest.raises((SourceError, SourceErrors), match="in_mode takes the name of a state"):
        compile_properties(f"property p:\n    always {call}\n", source="m.rv")


def test_in_mode_in_an_app_without_a_modes_chart_says_so(tmp_path):
    import shutil

    from rasm.platform.manifest import load_manifest
    from rasm.platform.signals import app_problems

    app = tmp_path / "hotbox"
    shutil.copytree(Path(__file__).resolve().parents[2] / "examples" / "hotbox", app)
    (app / "modes.rv").write_text('property parked:\n    always (in_mode("parked") -> true)\n')
    text = (app / "app.yaml").read_text().replace(
        "  - properties/hotbox.rv\n", "  - properties/hotbox.rv\n  - modes.rv\n"
    )
    (app / "app.yaml").write_text(text)
    [problem] = app_problems(load_manifest(app))
    assert (problem.location.line, problem.location.col) == (2, 13)
    assert problem.message == (
        "signal 'mode_parked' is not provided by any part of the app: in_mode(\"parked\") and "
        "mode_<state> read the managed system's modes chart, and the app has none "
        "(managed_system.modes)"
    )
