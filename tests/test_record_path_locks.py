"""The per-record paths take their locks with acquire()/release(), not `with`: each call leaves
its lock free again, when it returns and when it raises (another thread can take it at once).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import pytest
from sismic.clock import SimulatedClock

from rasm.comm.message import TransportStats
from rasm.errors import KnowledgeError
from rasm.knowledge.base import KnowledgeBase
from rasm.platform.scheduler import Scheduler


def _free_for_another_thread(lock: Any) -> bool:
    taken: list[bool] = []

    def take() -> None:
        got = lock.acquire(blocking=False)
        taken.append(got)
        if got:
            lock.release()

    thread = threading.Thread(target=take)
    thread.start()
    thread.join()
    return taken == [True]


def _kb() -> KnowledgeBase:
    kb = KnowledgeBase()
    kb.declare("speed", "float", minimum=0.0)
    kb.register_knowledge("speed", 1.0, 1.0)
    return kb


def _raises(call: Callable[[], Any]) -> None:
    with pytest.raises((KnowledgeError, TypeError)):
        call()


CALLS: dict[str, Callable[[], tuple[Any, Callable[[], Any]]]] = {
    "register_knowledge": lambda: (kb := _kb(), lambda: kb.register_knowledge("speed", 2.0, 2.0)),
    "register_knowledge refused": lambda: (
        kb := _kb(), lambda: _raises(lambda: kb.register_knowledge("speed", -1.0, 2.0))
    ),
    "register_values": lambda: (
        kb := _kb(), lambda: kb.register_values({"speed": -1.0, "other": 1}, 2.0)
    ),
    "register_values, a failing subscriber": lambda: (
        kb := _kb(),
        lambda: (kb.subscribe(lambda key, sample: 1 / 0), kb.register_values({"speed": 3.0}, 3.0)),
    ),
    "read_knowledge": lambda: (kb := _kb(), lambda: kb.read_knowledge("speed")),
    "history": lambda: (kb := _kb(), lambda: kb.history("speed", since=0.0)),
    "history, a bad bound": lambda: (
        kb := _kb(), lambda: _raises(lambda: kb.history("speed", since="soon"))
    ),
    "add_delivery": lambda: (stats := TransportStats(), lambda: stats.add_delivery(1, 0, 1)),
    "add_delivery, not a number": lambda: (
        stats := TransportStats(), lambda: _raises(lambda: stats.add_delivery("one", 0))
    ),
    "submit": lambda: (jobs := Scheduler(SimulatedClock()), lambda: jobs.submit(lambda: None)),
    "run_until, the inbox": lambda: (
        jobs := Scheduler(SimulatedClock()),
        lambda: (jobs.submit(lambda: None), jobs.run_until(1.0)),
    ),
}


@pytest.mark.parametrize("name", sorted(CALLS))
def test_each_call_leaves_its_lock_free(name):
    owner, call = CALLS[name]()
    call()
    free = _free_for_another_thread(owner._lock)
    assert free  # (not the owner in the assertion: its repr may want the lock)
