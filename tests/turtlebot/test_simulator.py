"""The managed system: deterministic for a seed, debris blinds its planner, spins are inserted."""

from __future__ import annotations

import math

import pytest
from tb4.simulator import TurtleBotSimulator
from tb4.world import generate_scenario

BLIND_AHEAD = {
    "room": [9.0, 5.0],
    "start": [1.0, 2.5, 0.0],
    "waypoints": [[8.0, 2.5]],
    "obstacles": [{"circle": [4.0, 2.5, 0.25]}],
    "occlusions": [{"start": 0.0, "center": 0.0, "width": 120.0}],
}


def drive(sim, seconds, dt=0.1, until=None):
    messages = []
    for k in range(int(round(seconds / dt))):
        messages.append(sim.step(k * dt, dt))
        if until is not None and until(sim):
            break
    return messages


def test_the_same_seed_gives_the_same_messages():
    scenario = generate_scenario(3)
    a = drive(TurtleBotSimulator(scenario, 5), 8.0)
    b = drive(TurtleBotSimulator(scenario, 5), 8.0)
    c = drive(TurtleBotSimulator(scenario, 6), 8.0)
    assert a == b
    assert a != c  # the noise depends on the seed


def test_published_scans_are_empty_where_the_debris_is():
    messages = drive(TurtleBotSimulator(BLIND_AHEAD, 1), 0.5)
    ranges = messages[0]["/safe-scan"]["ranges"]
    assert len(ranges) == 360
    assert all(ranges[i] is None for i in [*range(0, 61), *range(300, 360)])
    assert sum(r is None for r in ranges[61:300]) < 10  # only dropouts elsewhere
    assert [("/safe-scan" in m) for m in messages[:4]] == [True, False, True, False]  # 5 Hz


def test_an_obstacle_hidden_by_debris_is_hit_and_a_seen_one_is_not():
    blind = TurtleBotSimulator(BLIND_AHEAD, 1)
    drive(blind, 30.0, until=lambda s: s.collisions)
    assert blind.collisions == 1
    clear = TurtleBotSimulator({**BLIND_AHEAD, "occlusions": []}, 1)
    drive(clear, 40.0, until=lambda s: s.arrived_at is not None)
    assert clear.collisions == 0 and clear.arrived_at is not None


def test_a_spin_plan_stops_the_robot_and_sweeps_both_ways_back_to_its_heading():
    sim = TurtleBotSimulator({**BLIND_AHEAD, "obstacles": []}, 1)
    drive(sim, 2.0)
    heading = sim.yaw
    sim.apply(
        "spin_config",
        {"rotation": 45.0, "angular_velocity": 90.0, "stop_every": 4.0, "plan": "p1"},
        2.0,
    )
    yaws, modes, speeds, scanned = [], [], [], []
    for k in range(20, 60):
        messages = sim.step(k * 0.1, 0.1)
        out = messages["/odom"]
        yaws.append(out["yaw"])
        modes.append(out["nav_mode"])
        speeds.append(out["velocity"])
        if "/safe-scan" in messages:
            scanned.append(math.degrees(messages["/safe-scan"]["scan_pose"][2]))
    spin = [i for i, m in enumerate(modes) if m == "spin"]
    assert spin and spin[0] == 0  # a new plan spins at once
    assert all(speeds[i] == 0.0 or yaws[i] == yaws[i - 1] for i in spin[1:])  # turns standing
    # 45 left, 90 right, 45 back at 90 deg/s: 2 s turning (plus braking, and 0.2 s at each
    # end), then driving again
    assert max(yaws[: len(spin)]) == pytest.approx(math.degrees(heading) + 45, abs=0.01)
    assert min(yaws[: len(spin)]) == pytest.approx(math.degrees(heading) - 45, abs=0.01)
    end = spin[-1] + 1
    assert modes[end] == "navigate" and 24 <= len(spin) <= 29
    # a scan is taken at each end of the sweep
    for side in (45, -45):
        assert any(abs(y - math.degrees(heading) - side) < 0.01 for y in scanned), side
    assert yaws[end] == pytest.approx(math.degrees(heading), abs=0.5)
    assert sim.spin.spins == 1


def test_a_zero_rotation_plan_cancels_spinning():
    sim = TurtleBotSimulator({**BLIND_AHEAD, "obstacles": []}, 1)
    sim.apply("spin_config", {"rotation": 30.0, "angular_velocity": 90.0, "stop_every": 2.0}, 0.0)
    assert sim.spin.active
    sim.apply("spin_config", {"rotation": 0.0, "angular_velocity": 0.0, "stop_every": 0.0}, 0.0)
    drive(sim, 6.0)
    assert not sim.spin.active and sim.spin.spins == 0
