"""Knowledge in a real redis-server: the KnowledgeBase API, shared by several processes."""

from __future__ import annotations

import itertools
import queue
import subprocess
import sys
import textwrap

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import KnowledgeError
from rasm.knowledge import KnowledgeBase, RedisKnowledgeBase, RedisStorage, Sample, open_knowledge

_namespaces = itertools.count()


@pytest.fixture
def make(redis_server):
    """``make(**options)``: a RedisKnowledgeBase on a fresh namespace of the module's server
    (``same=True``: on the namespace of the previous one, as a second process would be)."""
    made: list[RedisKnowledgeBase] = []
    current = [f"t{next(_namespaces)}"]

    def factory(*, same: bool = False, **options) -> RedisKnowledgeBase:
        if not same:
            current[0] = f"t{next(_namespaces)}"
        kb = RedisKnowledgeBase(redis_server.url, namespace=current[0], **options)
        made.append(kb)
        return kb

    yield factory
    for kb in made:
        kb.close()


def test_it_is_a_knowledge_base_with_the_same_reads(make):
    kb = make()
    assert isinstance(kb, KnowledgeBase)
    kb.declare("temperature", "float", history=3, minimum=-40, maximum=150)
    for t in range(5):
        kb.register_knowledge("temperature", 20 + t, float(t))
    kb.register_knowledge("mode", "heat", 1.0)
    kb.register_knowledge("plan", {"steps": [1, 2], "to": "dock"}, 2.0)
    assert kb.read_knowledge("temperature") == 24.0
    assert kb.read_sample("temperature") == Sample(4.0, 24.0)
    assert kb.history("temperature") == [Sample(2.0, 22.0), Sample(3.0, 23.0), Sample(4.0, 24.0)]
    assert kb.history("temperature", last=2) == [Sample(3.0, 23.0), Sample(4.0, 24.0)]
    assert kb.history("temperature", since=2.5, until=3.5) == [Sample(3.0, 23.0)]
    assert kb.history("temperature", last=1, until=3.0) == [Sample(3.0, 23.0)]
    assert kb.history("nothing") == [] and kb.read_knowledge("nothing", 7) == 7
    assert kb.keys() == ["temperature", "mode", "plan"]
    assert kb.snapshot() == {
        "temperature": 24.0,
        "mode": "heat",
        "plan": {"steps": [1, 2], "to": "dock"},
    }
    assert "mode" in kb and "nothing" not in kb
    assert kb.declaration("mode").type == "str"
    assert list(kb.declarations()) == ["temperature", "mode", "plan"]


def test_the_same_checks_and_errors(make):
    kb, memory = make(), KnowledgeBase()
    for store in (kb, memory):
        store.declare("v", "float", maximum=1.0)
        store.register_knowledge("v", 0.5, 1.0)
    for value, time in (("fast", 2.0), (2.0, 2.0), (0.1, 0.5), (0.1, float("nan")), (True, 3.0)):
        with pytest.raises(KnowledgeError) as in_redis:
            kb.register_knowledge("v", value, time)
        with pytest.raises(KnowledgeError) as in_memory:
            memory.register_knowledge("v", value, time)
        assert str(in_redis.value) == str(in_memory.value)
    with pytest.raises(KnowledgeError, match="last must be"):
        kb.history("v", last=-1)
    assert kb.history("v") == memory.history("v") == [Sample(1.0, 0.5)]


operations = st.lists(
    st.tuples(
        st.sampled_from(["a", "b"]),
        st.integers(min_value=-3, max_value=3),
        st.floats(min_value=0, max_value=5, allow_nan=False).map(lambda t: round(t, 1)),
    ),
    max_size=25,
)


@settings(max_examples=40, deadline=None)
@given(ops=operations, history=st.integers(min_value=1, max_value=5), queries=st.data())
def test_redis_and_memory_agree_on_any_sequence(redis_server, ops, history, queries):
    """Whatever is registered (including refused writes), every read gives the same answer."""
    kb = RedisKnowledgeBase(redis_server.url, namespace=f"h{next(_namespaces)}")
    memory = KnowledgeBase()
    try:
        for store in (kb, memory):
            store.declare("a", "int", history=history)
        for key, value, time in ops:
            outcomes = []
            for store in (kb, memory):
                try:
                    outcomes.append(store.register_knowledge(key, value, time))
                except KnowledgeError as exc:
                    outcomes.append(str(exc))
            assert outcomes[0] == outcomes[1]
        assert kb.keys() == memory.keys()
        assert kb.snapshot() == memory.snapshot()
        for key in ("a", "b"):
            last = queries.draw(st.none() | st.integers(min_value=0, max_value=6))
            since = queries.draw(st.none() | st.floats(min_value=0, max_value=5))
            until = queries.draw(st.none() | st.floats(min_value=0, max_value=5))
            got = kb.history(key, last=last, since=since, until=until)
            assert got == memory.history(key, last=last, since=since, until=until)
            assert kb.read_sample(key) == memory.read_sample(key)
    finally:
        kb.clear()
        kb.close()


def test_redeclaring_converts_and_trims_for_everyone(make):
    a = make()
    b = make(same=True)
    a.register_knowledge("n", 1, 1.0)
    a.register_knowledge("n", 2, 2.0)
    a.register_knowledge("n", 3, 3.0)
    b.declare("n", "float", history=2)
    assert a.history("n") == [Sample(2.0, 2.0), Sample(3.0, 3.0)]
    assert isinstance(a.read_knowledge("n"), float)
    # a's cached declaration (int) is stale: its next write is checked against the new one
    a.register_knowledge("n", 4, 4.0)
    assert a.read_sample("n") == Sample(4.0, 4.0) and a.declaration("n").history == 2
    a.register_knowledge("s", "x", 1.0)
    with pytest.raises(KnowledgeError, match="does not fit"):
        b.declare("s", "int")
    assert a.read_knowledge("s") == "x" and a.declaration("s").type == "str"


def test_the_time_rule_holds_across_clients(make):
    a = make()
    b = make(same=True)
    a.register_knowledge("x", 1.0, 10.0)
    with pytest.raises(KnowledgeError, match="older than its last sample at 10.0"):
        b.register_knowledge("x", 2.0, 9.0)
    b.register_knowledge("x", 2.0, 10.0)  # equal times are fine, and keep their order
    assert a.history("x") == [Sample(10.0, 1.0), Sample(10.0, 2.0)]


def test_load_samples_does_not_notify(make):
    kb = make()
    seen = []
    kb.subscribe(lambda key, sample: seen.append((key, sample)))
    assert kb.load_samples("x", [Sample(1.0, 1.5), Sample(2.0, 2.5)]) == 2
    kb.register_knowledge("x", 3.5, 3.0)
    assert seen == [("x", Sample(3.0, 3.5))]
    assert kb.history("x") == [Sample(1.0, 1.5), Sample(2.0, 2.5), Sample(3.0, 3.5)]


def test_a_batch_keeps_the_stores_rules_and_reaches_batch_subscribers_at_once(make):
    kb = make()
    kb.declare("speed", "float", minimum=0.0)
    kb.register_knowledge("speed", 1.0, 5.0)
    batches = []
    kb.subscribe_batches(batches.append)
    refused = kb.register_values({"speed": 2.0, "mode": "dock"}, 4.0)  # speed: older than 5.0
    assert list(refused) == ["speed"] and "older than its last sample" in str(refused["speed"])
    assert batches == [[("mode", Sample(4.0, "dock"))]]
    assert kb.history("speed") == [Sample(5.0, 1.0)]


WRITER = textwrap.dedent(
    """
    import sys
    from rasm.knowledge import open_knowledge

    kb, storage = open_knowledge(sys.argv[1])
    kb.declare("velocity", "float", history=5)
    for i in range(8):
        kb.register_knowledge("velocity", i / 10, float(i))
    kb.register_knowledge("mode", "dock", 7.0)
    print(kb.read_knowledge("velocity"), flush=True)
    storage.close()
    """
)


def test_a_value_registered_in_one_process_is_read_in_another(redis_server, make):
    url = f"{redis_server.url}?namespace=shared{next(_namespaces)}"
    reader, storage = open_knowledge(url)
    assert isinstance(reader, RedisKnowledgeBase) and isinstance(storage, RedisStorage)
    seen: queue.Queue = queue.Queue()
    reader.subscribe(lambda key, sample: seen.put((key, sample)))
    done = subprocess.run(
        [sys.executable, "-c", WRITER, url], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "0.7"
    assert reader.read_knowledge("velocity") == 0.7
    assert reader.history("velocity") == [Sample(float(i), i / 10) for i in range(3, 8)]
    assert reader.snapshot() == {"velocity": 0.7, "mode": "dock"}
    assert reader.declaration("velocity").history == 5
    # the other process's registrations reached this process's subscriber, in order
    notified = [seen.get(timeout=10) for _ in range(9)]
    assert notified == [("velocity", Sample(float(i), i / 10)) for i in range(8)] + [
        ("mode", Sample(7.0, "dock"))
    ]
    # and this process writes on after it, under the same time rule
    with pytest.raises(KnowledgeError, match="older"):
        reader.register_knowledge("velocity", 0.0, 6.0)
    storage.close()


def test_storage_face_and_urls(redis_server):
    kb, storage = open_knowledge(f"{redis_server.url}?namespace=face{next(_namespaces)}")
    storage.register_knowledge_update("x", Sample(1.0, 1.0))
    storage.register_knowledge_update("x", Sample(2.0, 1.0))
    assert storage.update_persistency() == 2 and storage.update_persistency() == 0
    assert storage.restore(kb) == 0
    storage.close()
    assert storage.closed
    with pytest.raises(KnowledgeError, match="cannot reach the Redis knowledge store"):
        RedisKnowledgeBase("redis://127.0.0.1:1/0")
    with pytest.raises(KnowledgeError, match="namespace"):
        RedisKnowledgeBase(f"{redis_server.url}?namespace=a{{b}}")


def test_clear_empties_the_namespace_only(make):
    a = make()
    other = make()
    a.register_knowledge("x", 1, 1.0)
    other.register_knowledge("x", 2, 1.0)
    assert a.clear() == 1
    assert a.keys() == [] and a.read_sample("x") is None
    assert other.read_knowledge("x") == 2
    a.register_knowledge("x", 5, 0.0)  # a fresh timeline
    assert a.history("x") == [Sample(0.0, 5)]


def test_notices_resume_after_the_server_restarts(tmp_path):
    from rasm.testing.servers import start_redis

    server = start_redis(tmp_path)
    try:
        reader = RedisKnowledgeBase(server.url)
        writer = RedisKnowledgeBase(server.url)
        seen: queue.Queue = queue.Queue()
        reader.subscribe(lambda key, sample: seen.put((key, sample)))
        writer.register_knowledge("x", 1, 1.0)
        assert seen.get(timeout=10) == ("x", Sample(1.0, 1))
        server.restart()  # no persistence: a fresh, empty server on the same port
        # writes go through as soon as it is back (redis-py reconnects)...
        writer.register_knowledge("x", 2, 2.0)
        assert reader.read_sample("x") == Sample(2.0, 2)
        # ...and the reader's feed resubscribes: a later write is notified again (the notice
        # of a write made before it resubscribed may be lost: pub/sub keeps nothing)
        for t in range(3, 1000):
            writer.register_knowledge("x", t, float(t))
            try:
                key, sample = seen.get(timeout=0.5)
                break
            except queue.Empty:
                continue
        assert key == "x" and sample.value >= 2
        reader.close()
        writer.close()
    finally:
        server.stop()
