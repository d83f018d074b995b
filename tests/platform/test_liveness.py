"""Whether the managed system is there, and which readings are live: a probe silent past its
staleness makes its signals stale (properties reading them are in error, not judged on the last
reading) and the managed system lost, on the simulated clock; the rule itself for all inputs."""

from __future__ import annotations

from hypothesis import example, given
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.platform.liveness import ManagedSystemWatch
from rasm.platform.manifest import Probe, Signal

from .guarded import write_guarded_app


def test_a_dead_robot_leaves_no_property_satisfied_on_its_last_reading(tmp_path):
    # the robot dies at 4.0 and never comes back; its probe may stay silent for 1 s
    app = write_guarded_app(tmp_path / "app", staleness=1.0)
    platform = Platform(app, RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        scenario={"silent": [[4.0, 1000.0]]},
    ))
    records: list[dict] = []
    verdicts: list = []
    platform.on_record.append(lambda t, r: records.append({"time": t, **r}))
    platform.on_verdict.append(verdicts.append)
    summary = platform.run(12)
    # slow reads speed, which is stale from 4.5 on (the last reading came at 3.5)
    assert summary.verdicts["slow"] == "error"
    stale = [v for v in verdicts if v.property == "slow" and v.time >= 4.5]
    assert stale and all(v.value is False and "stale reading" in v.error for v in stale)
    assert all(v.error is None for v in verdicts if v.property == "slow" and v.time < 4.5)
    # it vetoed at once (a verdict at 4.5 itself, no record needed) and no action went out
    assert stale[0].time == 4.5
    assert not [r for r in records if r.get("executed") and r["time"] >= 4.5]
    assert any(r.get("executed") for r in records if r["time"] < 4.0)


def test_without_a_staleness_the_last_reading_is_held_as_before(tmp_path):
    # the same run, no staleness declared: sample-and-hold, as SPEC §4 says for any signal
    app = write_guarded_app(tmp_path / "app")
    platform = Platform(app, RunOptions(
        clock="simulated",
        seed=1,
        knowledge="memory",
        scenario={"silent": [[4.0, 1000.0]]},
    ))
    assert platform.run(12).verdicts["slow"] == "satisfied"


def _probe(staleness):
    return Probe("robot/odom", {"speed": Signal("speed", "float")}, staleness=staleness)


@given(
    staleness=st.sampled_from([0.5, 1.0, 2.5]),
    heard=st.lists(st.integers(0, 400), max_size=20).map(sorted),
    checks=st.lists(st.integers(0, 500), min_size=1, max_size=20).map(sorted),
)
@example(staleness=0.5, heard=[18], checks=[23])  # in floats, 2.3 - 1.8 < 0.5
def test_a_probe_is_stale_exactly_when_silent_for_its_staleness(staleness, heard, checks):
    # times in tenths of a second: the watch is told of each message and asked at each check
    now = [0.0]
    changes: list[bool] = []
    stale_now: list[dict] = [{}]
    watch = ManagedSystemWatch(
        [_probe(staleness)], clock=lambda: now[0],
        on_change=lambda lost, why: changes.append(lost),
        on_stale=lambda stale: stale_now.__setitem__(0, stale),
    )
    watch.begin()  # the run starts at 0
    events = sorted([(t, 0) for t in heard] + [(t, 1) for t in checks])
    for tenths, kind in events:
        now[0] = tenths / 10
        if kind == 0:
            watch.heard("robot/odom", now[0])
            continue
        watch.evaluate()
        # exactly, in tenths: heard at 1.8 and asked at 2.3, a staleness of 0.5 has passed
        last = max([t for t in heard if t <= tenths], default=0)
        expected = tenths - last >= round(staleness * 10)
        assert watch.online() is not expected
        assert ("speed" in stale_now[0]) is expected
        assert (watch.next_deadline() is None) is expected
    # every change reported once: lost and back alternate
    assert all(a != b for a, b in zip(changes, changes[1:], strict=False))


def test_presence_alone_counts_as_a_witness():
    there = [True]
    watch = ManagedSystemWatch([], clock=lambda: 0.0, presence=lambda: there[0])
    watch.begin()
    watch.evaluate()
    assert watch.online()
    there[0] = False
    watch.evaluate()
    assert not watch.online() and "presence" in watch.lost_why


def test_a_declared_publisher_that_left_the_graph_makes_its_probe_stale():
    graph = {"/robot"}
    probe = Probe("/odom", {"speed": Signal("speed", "float")}, type="nav_msgs/msg/Odometry",
                  publisher="/robot")
    stale: list[dict] = []
    watch = ManagedSystemWatch([probe], clock=lambda: 0.0, alive=graph.__contains__,
                               on_stale=stale.append)
    watch.begin()
    watch.evaluate()
    assert watch.online() and not stale
    graph.clear()
    watch.evaluate()
    assert not watch.online() and "/robot is not in the ROS graph" in stale[-1]["speed"]
