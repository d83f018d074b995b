"""properties/maple_k.rv's stage_order: the one check of the MAPLE-K stage order, on the trace.

Each stage writes its ``stage`` record as it starts, then the events it decided, as the platform
writes them. The broken loops below are those a broken orchestrator chart would run.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.testing import check_trace

MAPLE_K = Path(__file__).resolve().parents[2] / "properties" / "maple_k.rv"

# what each stage decides, on the records after its own
EVENTS = {
    "monitor": {},
    "analyse": {"anomaly": True},
    "plan": {"planned": True, "plan": "p"},
    "legitimate": {"legitimate": True, "plan": "p"},
    "rejected": {"rejected": True, "plan": "p"},  # a Legitimate stage that rejects the plan
    "execute": {"executed": True, "plan": "p"},
}


def trace(stages: list[str]) -> list[dict]:
    records = []
    for time, stage in enumerate(stages):
        name = "legitimate" if stage == "rejected" else stage
        records.append({"time": time, "stage": name, "duration": 0.001})
        if EVENTS[stage]:
            records.append({"time": time, **EVENTS[stage]})
    return records


def stage_order(stages: list[str]) -> str:
    report = check_trace(MAPLE_K, trace(stages))
    return next(p.verdict for p in report.properties if p.name == "stage_order")


FULL = ["monitor", "analyse", "plan", "legitimate", "execute"]


@pytest.mark.parametrize(
    "stages",
    [
        FULL + FULL,
        ["monitor", "analyse", "monitor", "analyse"],  # no anomaly: the loop starts again
        ["monitor", "analyse", "plan", "rejected", "plan", "legitimate", "execute"],  # replanning
        ["monitor", "analyse", "plan", "monitor"],  # a cancelled adaptation
    ],
    ids=["two iterations", "early stop", "replanning", "cancelled"],
)
def test_a_loop_in_order_satisfies_stage_order(stages):
    assert stage_order(stages) == "satisfied"


@pytest.mark.parametrize(
    "stages",
    [
        ["monitor", "analyse", "legitimate", "execute"],  # planning skipped
        ["monitor", "analyse", "plan", "legitimate", "plan"],  # an accepted plan planned again
        ["monitor", "analyse", "execute"],  # a failed stage goes on to execute
        ["monitor", "execute"],  # an iteration jumps to execute
    ],
    ids=["planning skipped", "accepted planned again", "failed executes", "jump"],
)
def test_a_stage_out_of_order_violates_stage_order(stages):
    assert stage_order(stages) == "violated"


# ------------------------------------------- the guarantees, with the fallback's actions among them

GUARANTEES = ("execute_only_legitimate_plans", "rejected_plans_stay_rejected")

# an iteration: how many plans Legitimate rejects, then what becomes of the last (None: the
# adaptation is cancelled after the rejections, or there was no anomaly when nothing was planned)
ITERATION = st.tuples(st.integers(0, 3), st.sampled_from(["executed", "dropped", None]))
# a delivery of the fallback's plan: its actions, each sent or dropped
DELIVERY = st.lists(st.booleans(), min_size=1, max_size=2)
LOOP = st.lists(st.one_of(ITERATION.map(lambda i: ("loop", i)),
                          DELIVERY.map(lambda d: ("fallback", d))), min_size=1, max_size=12)


def loop_records(steps) -> list[dict]:
    """The records the platform writes for these iterations and fallback deliveries, in order:
    a loop plan is planned, then rejected or accepted; the fallback's plan is accepted (proved
    before the run) before each delivery; an action goes out registered (trusted)."""
    records: list[dict] = []
    time, plans = 0, 0

    def at(stage: str | None, **events) -> None:
        nonlocal time
        time += 1
        if stage is not None:
            records.append({"time": time, "stage": stage, "duration": 0.001})
        if events:
            records.append({"time": time, **events})

    for kind, what in steps:
        if kind == "fallback":
            at(None, legitimate=True, plan="f1")
            for sent in what:
                if sent:
                    at(None, trusted=True, plan="f1")
                at(None, **{"executed" if sent else "dropped": True}, plan="f1")
            continue
        rejections, outcome = what
        at("monitor")
        if not rejections and outcome is None:
            at("analyse")  # no anomaly
            continue
        at("analyse", anomaly=True)
        for _ in range(rejections):
            plans += 1
            at("plan", planned=True, plan=f"p{plans}")
            at("legitimate", rejected=True, plan=f"p{plans}")
        if outcome is None:
            continue  # cancelled after its rejections
        plans += 1
        at("plan", planned=True, plan=f"p{plans}")
        at("legitimate", legitimate=True, plan=f"p{plans}")
        at("execute", trusted=True, plan=f"p{plans}")
        at(None, **{outcome: True}, plan=f"p{plans}")
    return records


def guarantees(records: list[dict]) -> dict[str, str]:
    report = check_trace(MAPLE_K, records)
    return {p.name: p.verdict for p in report.properties if p.name in GUARANTEES}


@settings(max_examples=150, deadline=None)
@given(steps=LOOP)
def test_the_guarantees_hold_on_every_loop_with_fallback_deliveries_anywhere(steps):
    """Fallback deliveries before any plan, right after a rejection or between plans: the loop
    and the fallback as the platform traces them never violate its guarantees."""
    assert set(guarantees(loop_records(steps)).values()) == {"satisfied"}


@settings(max_examples=100, deadline=None)
@given(steps=LOOP, rejections=st.integers(1, 3), fallback=st.booleans())
def test_an_action_after_a_rejection_with_no_acceptance_is_caught(steps, rejections, fallback):
    """The other way round: an action sent when the last word on a plan was a rejection (the
    rejected plan executed, or a fallback delivery that does not say its plan is legitimate)
    violates rejected_plans_stay_rejected, whatever came before."""
    records = loop_records([*steps, ("loop", (rejections, None))])
    plan = "f1" if fallback else records[-1]["plan"]
    time = records[-1]["time"] + 1
    records += [{"time": time, "trusted": True, "plan": plan},
                {"time": time, "executed": True, "plan": plan}]
    assert guarantees(records)["rejected_plans_stay_rejected"] == "violated"
