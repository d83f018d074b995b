"""Subscribers (the Monitor's wake-up, the trace writer) and use from several threads at once."""

from __future__ import annotations

import logging
import threading

from rasm.knowledge import KnowledgeBase, Sample

WAIT = 10.0  # seconds: only a bound against a hang, never a synchronisation


def test_subscribers_see_every_registration_in_order_until_cancelled():
    kb = KnowledgeBase()
    seen: list[tuple[str, Sample]] = []
    handle = kb.subscribe(lambda key, sample: seen.append((key, sample)))
    a = kb.register_knowledge("a", 1, 0.0)
    b = kb.register_knowledge("b", "x", 0.5)
    handle()  # the handle is callable
    kb.register_knowledge("a", 2, 1.0)
    handle.cancel()  # and cancelling twice is harmless
    assert seen == [("a", a), ("b", b)]


def test_a_failing_subscriber_is_logged_and_never_reaches_the_writer(caplog):
    kb = KnowledgeBase()
    after: list[str] = []

    def broken(key, sample):
        raise RuntimeError("subscriber bug")

    kb.subscribe(broken)
    kb.subscribe(lambda key, sample: after.append(key))
    with caplog.at_level(logging.ERROR, logger="rasm.knowledge"):
        sample = kb.register_knowledge("a", 1.0, 0.0)
    assert sample == Sample(0.0, 1.0)
    assert kb.read_knowledge("a") == 1.0
    assert after == ["a"]  # the next subscriber still ran
    assert "subscriber bug" in caplog.text
    assert "knowledge subscriber" in caplog.text


def test_a_subscriber_may_read_the_store_it_is_called_from():
    kb = KnowledgeBase()
    read: list[object] = []
    kb.subscribe(lambda key, sample: read.append(kb.read_knowledge(key)))
    kb.register_knowledge("a", 5, 0.0)
    assert read == [5]


def test_a_monitor_thread_wakes_on_a_registration_from_another_thread():
    kb = KnowledgeBase()
    woken = threading.Event()
    kb.subscribe(lambda key, sample: woken.set() if key == "anomaly" else None)
    writer = threading.Thread(target=kb.register_knowledge, args=("anomaly", True, 1.0))
    writer.start()
    assert woken.wait(WAIT)
    writer.join(WAIT)
    assert kb.read_knowledge("anomaly") is True


def test_concurrent_writers_and_readers_lose_nothing_and_see_consistent_histories():
    threads, per_thread = 4, 2000
    kb = KnowledgeBase(default_history=threads * per_thread)
    kb.declare("own", "int")  # touched by declare while writers run
    notified = [0]
    kb.subscribe(lambda key, sample: notified.__setitem__(0, notified[0] + 1))
    start = threading.Barrier(threads + 1)
    done = threading.Event()
    problems: list[str] = []

    def write(t: int) -> None:
        start.wait()
        for i in range(per_thread):
            kb.register_knowledge(f"own{t}", i, float(i))  # its own key, its own times
            kb.register_knowledge("shared", [t, i], 0.0)  # one key for all, equal times

    def read() -> None:
        start.wait()
        while not done.is_set():
            for t in range(threads):
                values = [s.value for s in kb.history(f"own{t}", since=0.0)]
                if values != list(range(len(values))):
                    problems.append(f"own{t} out of order")
            kb.snapshot()

    workers = [threading.Thread(target=write, args=(t,)) for t in range(threads)]
    reader = threading.Thread(target=read)
    for thread in [*workers, reader]:
        thread.start()
    for thread in workers:
        thread.join(WAIT * 6)
    done.set()
    reader.join(WAIT)
    assert not problems
    assert notified[0] == 2 * threads * per_thread
    shared = kb.history("shared")
    assert len(shared) == threads * per_thread
    for t in range(threads):  # each thread's writes kept their order in the shared ring
        assert [v[1] for v in (s.value for s in shared) if v[0] == t] == list(range(per_thread))
        assert kb.read_knowledge(f"own{t}") == per_thread - 1
