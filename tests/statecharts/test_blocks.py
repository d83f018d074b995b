"""The core tasks of the building blocks other than the orchestrator (the `initialized` mode)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from .support import BRING_UP, chart_path, entered, load, sent, start


def up(name: str, **context):
    run = start(load(chart_path(name)), context=context or None)
    run.send_all(BRING_UP)
    return run


def task(run) -> str:
    """The active sub-state of `initialized`."""
    (state,) = set(run.configuration) - {"lifecycle", "initialized"}
    return state


# Each block's core task as (event, sub-state after it) from the sub-state it starts in: the round
# trips the block drivers rely on.
ROUND_TRIPS = {
    "core": [("blocks_started", "running"), ("shutdown_requested", "stopping_blocks"),
             ("blocks_stopped", "stopped")],
    "adaptation_manager": [("action_requested", "checking_trustworthiness"),
                           ("trustworthy", "registering"), ("registered", "waiting")],
    "state_manager": [("status_changed", "recording"), ("status_recorded", "tracking")],
    "logging_and_tracking": [("log_received", "writing"), ("log_written", "ready"),
                             ("logging_disabled", "muted"), ("log_received", "muted"),
                             ("logging_enabled", "ready")],
    "trustworthiness_manager": [("check_requested", "gathering_evidence"),
                                ("evidence_gathered", "evaluating"), ("untrustworthy", "waiting")],
    "trustworthiness_checker": [("register_requested", "checking_action"),
                                ("action_refused", "monitoring"),
                                ("spec_update_requested", "reconfiguring"),
                                ("spec_updated", "monitoring")],
    "knowledge_manager": [("register_requested", "registering"), ("knowledge_registered", "ready"),
                          ("read_requested", "reading"), ("knowledge_read", "ready")],
    "communication_manager": [("publish_requested", "publishing"), ("published", "ready"),
                              ("subscribe_requested", "subscribing"), ("subscribed", "ready"),
                              ("connection_lost", "reconnecting"), ("reconnected", "ready")],
    "telegraf": [("data_received", "digesting"), ("digested", "waiting"),
                 ("data_received", "digesting"), ("record_rejected", "waiting")],
    "storage_manager": [("update_registered", "dirty"), ("persist_requested", "persisting"),
                        ("persisted", "idle")],
}


@pytest.mark.parametrize("name", sorted(ROUND_TRIPS))
def test_core_task_round_trip(name):
    run = up(name)
    for event, expected in ROUND_TRIPS[name]:
        run.send(event)
        assert task(run) == expected, (event, run.configuration)


def test_core_counts_blocks_in_fault_and_runs_again_when_the_last_recovers():
    run = up("core")
    run.send_all(["blocks_started", "block_failed", "block_failed"])
    assert task(run) == "recovering_blocks" and run.context["blocks_in_fault"] == 2
    run.send("block_recovered")
    assert task(run) == "recovering_blocks" and run.context["blocks_in_fault"] == 1
    run.send("block_recovered")
    assert task(run) == "running" and run.context["blocks_in_fault"] == 0


def test_core_shutdown_during_start_up_stops_the_started_blocks():
    run = up("core")
    run.send("shutdown_requested")
    assert task(run) == "stopping_blocks"


@pytest.mark.parametrize("refusal", ["untrustworthy", "registration_refused"])
def test_adaptation_manager_drops_an_action_that_is_not_trustworthy_or_not_registered(refusal):
    run = up("adaptation_manager")
    run.send("action_requested", action="rotate", kind="adaptation")
    if refusal == "registration_refused":
        run.send("trustworthy")
    run.send(refusal)
    assert task(run) == "dropping"
    run.send("dropped")
    assert task(run) == "waiting"
    assert run.context["actions_dropped"] == 1 and run.context["actions_registered"] == 0


@pytest.mark.parametrize("stage", ["checking_trustworthiness", "registering"])
def test_adaptation_manager_drops_an_action_whose_check_overruns(stage):
    run = up("adaptation_manager", check_budget=0.5)
    run.send("action_requested")
    if stage == "registering":
        run.send("trustworthy")
    run.advance_to(0.499)
    assert task(run) == stage
    taken = run.advance_to(0.5)
    assert task(run) == "dropping" and sent(taken) == ["check_timeout"]
    run.send("trustworthy")  # too late: the answer no longer registers anything
    assert task(run) == "dropping"


@pytest.mark.parametrize("stage", ["gathering_evidence", "evaluating"])
def test_trustworthiness_manager_abandons_an_overrunning_check(stage):
    run = up("trustworthiness_manager", check_budget=2.0)
    run.send("check_requested")
    if stage == "evaluating":
        run.send("evidence_gathered")
    taken = run.advance_to(2.0)
    assert task(run) == "waiting" and sent(taken) == ["check_timeout"]


def test_trustworthiness_checker_counts_violations_in_any_sub_state():
    run = up("trustworthiness_checker")
    run.send("violation_detected", property="velocity_limit")
    run.send("register_requested")
    run.send("violation_detected")
    assert task(run) == "checking_action" and run.context["violations"] == 2


def test_communication_manager_faults_when_reconnecting_overruns_its_budget():
    run = up("communication_manager", reconnect_budget=3.0)
    run.send("publish_requested")
    run.send("connection_lost")
    run.advance_to(2.0)
    run.send("connection_lost")  # a repeated notice does not restart the budget
    assert task(run) == "reconnecting"
    run.advance_to(3.0)
    assert run.configuration == ["lifecycle", "fault"]
    assert run.context["failure_reason"] == "reconnect_budget exceeded"


def test_telegraf_counts_digested_and_rejected_records():
    run = up("telegraf")
    run.send_all(["data_received", "digested", "data_received", "record_rejected"])
    assert (run.context["records_digested"], run.context["records_rejected"]) == (1, 1)


def test_storage_manager_flushes_at_the_latest_one_period_after_the_first_update():
    run = up("storage_manager", flush_period=2.0)
    run.send("update_registered")
    run.advance_to(1.0)
    run.send("update_registered")  # a later update does not postpone the flush
    assert task(run) == "dirty" and run.context["pending_updates"] == 2
    taken = run.advance_to(2.0)
    assert "persisting" in entered(taken)
    assert (run.context["batch"], run.context["pending_updates"]) == (2, 0)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.sampled_from(
                ["update_registered", "persist_requested", "persisted", "persist_failed"]
            ),
            st.floats(min_value=0.0, max_value=3.0),
        ),
        max_size=40,
    )
)
def test_storage_manager_never_loses_an_update(script):
    """Every registered update is persisted exactly once or is still pending/being persisted:
    persisted + pending + batch == registered, whatever the order of events and timeouts."""
    run = up("storage_manager", flush_period=1.0)
    registered = persisted = 0
    for item in script:
        if isinstance(item, float):
            run.advance(item)
            continue
        batch_before = run.context["batch"]
        in_flight = task(run) == "persisting"
        run.send(item)
        registered += item == "update_registered"
        if item == "persisted" and in_flight:
            persisted += batch_before
        ctx = run.context
        assert persisted + ctx["pending_updates"] + ctx["batch"] == registered
        assert (task(run) == "idle") == (ctx["pending_updates"] == 0 and ctx["batch"] == 0)
