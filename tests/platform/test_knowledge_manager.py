"""The Knowledge Manager registers knowledge only while it runs; a refused value stops no other."""

from __future__ import annotations

import pytest

from rasm.errors import PlatformError
from rasm.knowledge import KnowledgeBase
from rasm.platform.knowledge_manager import KnowledgeManager


def test_knowledge_manager_batches_refuse_each_bad_value_and_everything_when_not_running():
    store = KnowledgeBase()
    store.declare("speed", "float", minimum=0.0)
    km = KnowledgeManager(store)
    refused = km.register_values({"speed": 1.0, "mode": "x"}, 0.0)
    assert list(refused) == ["speed", "mode"]
    assert all(isinstance(e, PlatformError) for e in refused.values())
    km.send("configure")
    refused = km.register_values({"speed": -1.0, "mode": "x"}, 1.0)
    assert list(refused) == ["speed"] and "below the declared minimum" in str(refused["speed"])
    assert km.read_knowledge("mode") == "x"


def test_knowledge_manager_registers_one_value_at_the_clock_time_only_when_running():
    store = KnowledgeBase()
    km = KnowledgeManager(store)
    with pytest.raises(PlatformError, match="not initialized"):
        km.register_knowledge("speed", 1.0)
    km.send("configure")
    km.clock.time = 2.5
    sample = km.register_knowledge("speed", 1.0)
    assert (sample.time, sample.value) == (2.5, 1.0)
    assert km.read_knowledge("speed") == 1.0 and km.read_knowledge("other", "none") == "none"
