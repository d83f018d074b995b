"""The digital twin learning online: what it learned reaches knowledge, the trace and the
orchestrator; a twin that fails or reports a bad residual stops nothing."""

from __future__ import annotations

import logging

from rasm.knowledge.base import KnowledgeBase
from rasm.logs import RepeatedLogs
from rasm.platform.twin_learning import TwinLearning
from rasm.twin import DigitalTwin, TwinUpdate


class Scripted(DigitalTwin):
    """A twin that answers each observation with the next of ``updates`` (an exception is
    raised) and remembers what it was shown."""

    inputs = ("temperature", "heater_power")

    def __init__(self, *updates):
        self.updates = list(updates)
        self.seen = []

    def observe(self, time, values):
        self.seen.append((time, values))
        update = self.updates.pop(0)
        if isinstance(update, BaseException):
            raise update
        return update

    def simulate(self, plan, state, horizon, dt):
        return []

    def model(self):
        return {"version": 2, "params": {}}

    def load(self, model):
        pass


def learning(twin):
    """The twin's learning over a real knowledge base, with what it passed on recorded."""
    kb = KnowledgeBase()
    kb.declare("twin_residual", "float", minimum=0.0)
    out = {"registered": [], "emitted": [], "refused": [], "drifts": 0}

    def drift():
        out["drifts"] += 1

    learn = TwinLearning(
        twin,
        knowledge=kb,
        store=kb.register_knowledge,
        register=lambda values, time: out["registered"].append((time, values)),
        emit=lambda time, record: out["emitted"].append((time, record)),
        refused=lambda key, value, exc: out["refused"].append((key, value)),
        drift=drift,
        logs=RepeatedLogs(),
    )
    return learn, kb, out


def test_the_twin_reads_its_inputs_and_its_residual_model_and_drift_go_on():
    twin = Scripted(TwinUpdate(0.25, drift=True, model_changed=True))
    learn, kb, out = learning(twin)
    kb.register_knowledge("temperature", 20.0, 1.0)
    assert learn.reads({"temperature"}) and not learn.reads({"speed"})
    stored = {"temperature": 20.0}
    learn.observe(1.0, stored)
    assert twin.seen == [(1.0, {"temperature": 20.0, "heater_power": None})]
    assert stored == {"temperature": 20.0, "twin_residual": 0.25}
    assert kb.read_knowledge("twin_residual") == 0.25
    assert out["registered"] == [(1.0, {"twin_model": {"version": 2, "params": {}}})]
    assert [record for _, record in out["emitted"]] == [
        {"twin_model_version": 2},
        {"drift": True, "explanation": "the digital twin detected drift"},
    ]
    assert out["drifts"] == 1


def test_a_residual_knowledge_refuses_is_logged_and_left_out_of_the_record():
    learn, kb, out = learning(Scripted(TwinUpdate(-1.0)))  # below the declared minimum
    stored = {"temperature": 20.0}
    learn.observe(1.0, stored)
    assert stored == {"temperature": 20.0}
    assert kb.read_knowledge("twin_residual") is None
    assert [key for key, _ in out["refused"]] == ["twin_residual"]


def test_a_failing_twin_is_logged_once_then_counted_and_learning_goes_on(caplog):
    twin = Scripted(ValueError("bad fit"), ValueError("bad fit"), TwinUpdate(0.5))
    learn, kb, out = learning(twin)
    with caplog.at_level(logging.ERROR, logger="rasm.platform"):
        for time in (1.0, 2.0, 3.0):
            stored = {"temperature": 20.0}
            learn.observe(time, stored)
    failures = [r.getMessage() for r in caplog.records if "failed to learn" in r.getMessage()]
    assert len(failures) == 1 and "bad fit" in failures[0]
    assert sum(learn.logs.totals.values()) == 2
    assert stored["twin_residual"] == 0.5 and len(twin.seen) == 3
    assert out["emitted"] == [] and out["drifts"] == 0
