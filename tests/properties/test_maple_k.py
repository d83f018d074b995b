"""properties/maple_k.rv's stage_order: the one check of the MAPLE-K stage order, on the trace.

Each stage writes its ``stage`` record as it starts, then the events it decided, as the platform
writes them. The broken loops below are those a broken orchestrator chart would run.
"""

from __future__ import annotations

from pathlib import Path

import pytest

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
