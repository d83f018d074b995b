"""The State Manager follows every block's mode and keeps each stage's timing."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from rasm.knowledge import KnowledgeBase
from rasm.platform.knowledge_manager import KnowledgeManager
from rasm.platform.state_manager import StateManager


def test_the_modes_of_the_tracked_blocks_follow_their_charts() -> None:
    sm = StateManager()
    km = KnowledgeManager(KnowledgeBase())
    sm.track(km)
    assert sm.get_status("km") == "instantiated"
    km.send("configure")
    assert sm.get_status() == {"km": "initialized"}
    km.send("terminate")
    assert sm.get_status("km") == "terminated" and sm.get_status("other") is None


@given(st.lists(st.floats(0, 10), min_size=1, max_size=50), st.sampled_from([50, 90, 99]))
def test_a_percentile_is_the_nearest_rank_of_the_recorded_durations(durations, q) -> None:
    sm = StateManager()
    for start, duration in enumerate(durations):
        sm.record_stage("plan", float(start), duration)
    p = sm.percentiles("plan")[f"p{q}"]
    # the smallest recorded duration with at least q % of them at or below it
    assert p in durations
    assert sum(d <= p for d in durations) >= math.ceil(q / 100 * len(durations))
    assert sum(d < p for d in durations) < math.ceil(q / 100 * len(durations))


def test_a_stage_never_timed_has_no_percentiles_and_old_timings_are_forgotten() -> None:
    sm = StateManager(timing_history=3)
    assert sm.percentiles("monitor") == {}
    for start, duration in enumerate([9.0, 1.0, 2.0, 3.0]):
        sm.record_stage("monitor", float(start), duration)
    assert sm.percentiles("monitor") == {"p50": 2.0, "p90": 3.0, "p99": 3.0}


def test_the_presence_of_remote_processes_is_recorded() -> None:
    sm = StateManager()
    sm.set_node("hotbox-managed-1", "online")
    sm.set_node("hotbox-managed-1", "silent")
    assert sm.nodes == {"hotbox-managed-1": "silent"}
