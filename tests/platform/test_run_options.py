"""The run's options are one checked value: a clock or role by name or as the enum, anything else
refused with the choices; a replay fixes its clock and transport."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm import Clock, Platform, Role, RunOptions
from rasm.errors import PlatformError

from .conftest import HOTBOX


@given(role=st.sampled_from(list(Role)), clock=st.sampled_from(list(Clock)),
       by_name=st.booleans())
def test_a_clock_and_a_role_are_taken_by_name_or_as_the_enum(role, clock, by_name):
    options = RunOptions(role=role.value if by_name else role,
                         clock=clock.value if by_name else clock)
    assert options.role is role and options.clock is clock


@given(st.text(max_size=12).filter(lambda t: t not in {m.value for m in Role}))
def test_an_unknown_role_is_refused_with_the_choices(text):
    with pytest.raises(PlatformError, match=r"unknown role .* \(all, managing or managed\)"):
        RunOptions(role=text)


@given(st.text(max_size=12).filter(lambda t: t not in {m.value for m in Clock}))
def test_an_unknown_clock_is_refused_with_the_choices(text):
    with pytest.raises(PlatformError, match=r"unknown clock .* \(simulated or wall\)"):
        RunOptions(clock=text)


def test_which_side_a_role_runs():
    assert [(r.manages, r.runs_managed_system) for r in Role] == [
        (True, True), (True, False), (False, True)
    ]


def test_a_replay_runs_on_the_simulated_clock_over_the_local_bus_and_nothing_else():
    options = RunOptions(replay="run.mcap")
    assert options.clock is Clock.SIMULATED and options.transport == "local"
    for other in ({"role": "managing"}, {"clock": "wall"}, {"transport": "mqtt://127.0.0.1:1"}):
        with pytest.raises(PlatformError, match="a replay drives the loop from the recording"):
            RunOptions(replay="run.mcap", **other)


def test_an_unseeded_run_is_seed_0_and_the_app_s_scenario_is_the_default(hotbox):
    options = RunOptions(seed=None)
    assert options.seed == 0
    assert options.scenario_of(hotbox) == hotbox.scenario
    assert RunOptions(scenario={"x": 1}).scenario_of(hotbox) == {"x": 1}


def test_the_platform_takes_the_options_whole():
    with pytest.raises(TypeError, match="takes a RunOptions, not dict"):
        Platform(HOTBOX, {"clock": "simulated"})
    platform = Platform(HOTBOX, RunOptions(clock="simulated", seed=3))
    assert platform.clock_kind is Clock.SIMULATED and platform.options.seed == 3
