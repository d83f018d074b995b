"""Plan: the least sweep that covers every occluded ray, and plans the rules accept."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tb4.navigation import sweep_targets
from tb4.occlusion import Window
from tb4.spin import covered, dilate, mask_of, required_rotation, spin_plan

from rasm.rules import RuleSet

from .conftest import APP
from .strategies import windows

RULES = RuleSet.load(Path(APP) / "rules" / "turtlebot.yaml")


@settings(max_examples=150, deadline=None)
@given(windows(max_windows=4, min_gap=0), st.integers(0, 8))
def test_the_planned_sweep_covers_every_occluded_ray_and_no_smaller_one_does(case, margin):
    rays, ws = case
    mask = mask_of(ws, rays)
    need = required_rotation(mask, margin)
    if need is None:  # no ray stays clear of the widened debris: no sweep can help
        assert all(dilate(mask, margin)) and any(mask)
        return
    assert covered(mask, need, margin)
    if need > 0:
        assert not covered(mask, need - 1, margin)
    else:
        assert not any(mask)


@settings(max_examples=100, deadline=None)
@given(windows(rays=360, max_windows=3, min_length=3))
def test_plans_satisfy_the_rules_when_the_sweep_is_within_them(case):
    rays, ws = case
    plan = spin_plan(ws, rays)
    need = required_rotation(mask_of(ws, rays), 5)
    if need is None:
        assert plan is None
        return
    decision = RULES.evaluate(plan, {})
    assert plan["rotation"] == need * 360 / rays
    assert decision.accepted == (plan["rotation"] <= 150), decision.broken
    if plan["rotation"] > 0:
        # the sweep visits +rotation, -rotation and the heading: four half-sweeps of turning
        points = [0.0, *sweep_targets(plan["rotation"])]
        path = sum(abs(b - a) for a, b in zip(points, points[1:], strict=False))
        assert path == pytest.approx(4 * plan["rotation"])
        assert plan["angular_velocity"] * plan["spin_duration"] >= path


def test_a_front_window_needs_half_its_width_and_the_margin():
    # 121 rays centred ahead (-60..60 deg): the middle ray must turn 60 + 1 + 5 rays
    assert required_rotation(mask_of([Window(300, 121)], 360), margin=5) == 66


def test_a_clear_scanner_needs_no_spin_and_a_blind_one_cannot_be_helped():
    assert required_rotation([False] * 36) == 0
    assert spin_plan([], 36)["rotation"] == 0.0
    assert required_rotation([True] * 36) is None
    assert spin_plan([Window(0, 36)], 36) is None
