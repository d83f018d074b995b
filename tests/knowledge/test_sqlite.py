"""The Storage Manager's SQLite engine, on real files."""

from __future__ import annotations

import json
import logging
import math
import os
import sqlite3
import tempfile
import threading
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.knowledge import Declaration, KnowledgeBase, KnowledgeError, Sample, SqliteStorage

from .support import VALUES, same

SETTINGS = settings(max_examples=60, deadline=None)


def rows(path: Path, key: str) -> list[tuple[float, object]]:
    """What is on disk, read by another connection (WAL lets readers in while a writer is open):
    the (time, value) pairs of the key's batches, oldest first."""
    with sqlite3.connect(path) as db:
        batches = db.execute(
            'SELECT times, "values" FROM batches WHERE key = ? ORDER BY seq', (key,)
        ).fetchall()
    pairs = (zip(json.loads(times), json.loads(values), strict=True) for times, values in batches)
    return [pair for batch in pairs for pair in batch]


def restored(path: Path, **kwargs) -> KnowledgeBase:
    kb = KnowledgeBase(**kwargs)
    with SqliteStorage(path) as storage:
        storage.restore(kb)
    return kb


# -- round trips ----------------------------------------------------------------------------------


@pytest.mark.slow
@SETTINGS
@given(st.sampled_from(sorted(VALUES)), st.data())
def test_persistence_round_trips_every_value_of_every_declared_type(kind, data):
    values = data.draw(st.lists(VALUES[kind], min_size=1, max_size=8))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        kb.declare("k", kind, history=50)
        with SqliteStorage(path) as storage:
            storage.attach(kb)
            written = [kb.register_knowledge("k", v, i * 0.25) for i, v in enumerate(values)]
            assert storage.update_persistency() == len(values)
        back = restored(path)
        assert back.declaration("k") == Declaration("k", kind, 50)
        got = back.history("k")
        assert [s.time for s in got] == [s.time for s in written]
        assert all(same(a.value, b.value) for a, b in zip(got, written, strict=True))


def test_bounds_and_declarations_without_samples_are_persisted():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        big = 2**70  # an int bound must keep every digit
        kb.declare("count", "int", history=3, minimum=-big, maximum=big)
        kb.declare("speed", "float", minimum=0, maximum=1.5)
        with SqliteStorage(path) as storage:
            storage.attach(kb)
            assert storage.update_persistency() == 0  # no samples, declarations written
        back = restored(path)
        assert back.declarations() == kb.declarations()


# -- retention ------------------------------------------------------------------------------------


@pytest.mark.slow
@SETTINGS
@given(
    st.integers(1, 40),
    st.lists(st.lists(st.sampled_from("abc"), max_size=50), min_size=1, max_size=8),
)
def test_disk_keeps_the_last_keep_samples_per_key_and_at_most_a_sixteenth_more(keep, batches):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        written: dict[str, list[Sample]] = {k: [] for k in "abc"}
        clock = 0.0
        with SqliteStorage(path, keep=keep) as storage:
            storage.attach(kb)
            for batch in batches:
                for key in batch:
                    clock += 1.0
                    written[key].append(kb.register_knowledge(key, int(clock), clock))
                expected = sum(min(keep, batch.count(k)) for k in "abc")
                assert storage.update_persistency() == expected  # no row that would be pruned
                for key in "abc":
                    on_disk = [(t, int(v)) for t, v in rows(path, key)]
                    every = [(s.time, s.value) for s in written[key]]
                    assert min(keep, len(every)) <= len(on_disk) <= keep + keep // 16
                    assert on_disk == every[len(every) - len(on_disk):]  # the newest ones


def test_restore_gives_back_the_last_history_samples():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        kb.declare("v", "int", history=4)
        with SqliteStorage(path, keep=100) as storage:
            storage.attach(kb)
            for i in range(10):
                kb.register_knowledge("v", i, float(i))
        assert len(rows(path, "v")) == 10  # close() flushed
        assert [s.value for s in restored(path).history("v")] == [6, 7, 8, 9]


# -- transactions and failures --------------------------------------------------------------------


def test_a_failed_write_leaves_the_file_unchanged_and_keeps_the_samples_for_the_next():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        with SqliteStorage(path) as storage:
            storage.attach(kb)
            kb.register_knowledge("a", "fine", 0.0)
            storage.update_persistency()
            # a real SQL failure in the middle of the transaction, from another connection
            with sqlite3.connect(path) as other:
                other.execute(
                    "CREATE TRIGGER boom BEFORE INSERT ON batches WHEN NEW.key = 'b' "
                    "BEGIN SELECT RAISE(ABORT, 'disk says no'); END"
                )
            kb.register_knowledge("a", "before", 1.0)
            kb.register_knowledge("b", "boom", 2.0)
            with pytest.raises(KnowledgeError, match="cannot write knowledge to .*disk says no"):
                storage.update_persistency()
            assert rows(path, "a") == [(0.0, "fine")]  # "before" rolled back with the rest
            assert rows(path, "b") == []
            kb.register_knowledge("a", "after", 3.0)
            with sqlite3.connect(path) as other:
                other.execute("DROP TRIGGER boom")
            assert storage.update_persistency() == 3
        assert [v for _, v in rows(path, "a")] == ["fine", "before", "after"]
        assert rows(path, "b") == [(2.0, "boom")]


def test_close_flushes_is_idempotent_and_a_closed_storage_refuses_updates():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        storage = SqliteStorage(path)
        storage.attach(kb)
        kb.register_knowledge("a", 1.5, 0.0)
        storage.close()
        storage.close()
        assert storage.closed and storage.knowledge is None
        kb.register_knowledge("a", 2.5, 1.0)  # detached: the knowledge base goes on alone
        with pytest.raises(KnowledgeError, match="is closed"):
            storage.register_knowledge_update("a", Sample(2.0, 3.5))
        with pytest.raises(KnowledgeError, match="is closed"):
            storage.update_persistency()
        assert rows(path, "a") == [(0.0, 1.5)]


def test_wal_journal_and_the_synchronous_level():
    with tempfile.TemporaryDirectory() as tmp:
        for durable, level in [(False, 1), (True, 2)]:  # NORMAL, FULL
            path = Path(tmp) / f"k{durable}.db"
            with SqliteStorage(path, durable=durable) as storage:
                assert storage._db.execute("PRAGMA synchronous").fetchone()[0] == level
            with sqlite3.connect(path) as db:
                assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


# -- direct use (no attached knowledge base) ------------------------------------------------------


def test_register_knowledge_update_checks_type_and_time_then_persists():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        with SqliteStorage(path) as storage:
            storage.register_knowledge_update("v", Sample(1.0, 2))  # int inferred
            with pytest.raises(KnowledgeError, match="'v': expected int, got str"):
                storage.register_knowledge_update("v", Sample(2.0, "x"))
            with pytest.raises(KnowledgeError, match="'v': time 0.5 is not finite or older"):
                storage.register_knowledge_update("v", Sample(0.5, 3))
            storage.register_knowledge_update("v", (2, 3))  # a plain (time, value) pair
            assert storage.update_persistency() == 2
            with pytest.raises(KnowledgeError, match="'v': time 1.5 is not finite or older"):
                storage.register_knowledge_update("v", Sample(1.5, 3))  # older than flushed
        # a reopened storage remembers the type and the last time
        with SqliteStorage(path) as storage:
            with pytest.raises(KnowledgeError, match="'v': time 1.0 is not finite or older"):
                storage.register_knowledge_update("v", Sample(1.0, 4))
            with pytest.raises(KnowledgeError, match="expected int"):
                storage.register_knowledge_update("v", Sample(3.0, True))
        assert restored(path).history("v") == [Sample(1.0, 2), Sample(2.0, 3)]


def test_samples_a_knowledge_base_accepted_are_buffered_as_they_are(tmp_path):
    # the Storage Manager's path: the storage is not attached, the knowledge base checked them
    path = tmp_path / "k.db"
    kb = KnowledgeBase()
    kb.declare("speed", "float", history=20)
    with SqliteStorage(path) as storage:
        kb.subscribe(storage.buffer)
        for i in range(5):
            kb.register_knowledge("speed", i, i / 10)  # ints: the knowledge base keeps floats
        kb.register_knowledge("mode", "a, b", 0.5)  # undeclared: its type is its first value's
        assert storage.update_persistency() == 6
    assert rows(path, "speed") == [(i / 10, float(i)) for i in range(5)]
    assert rows(path, "mode") == [(0.5, "a, b")]
    back = restored(path)
    assert back.declaration("mode") == Declaration("mode", "str")
    assert [s.value for s in back.history("speed")] == [0.0, 1.0, 2.0, 3.0, 4.0]


# -- restore rules --------------------------------------------------------------------------------


def _file_with(path: Path, key: str, values: list[object]) -> None:
    kb = KnowledgeBase()
    with SqliteStorage(path) as storage:
        storage.attach(kb)
        for i, value in enumerate(values):
            kb.register_knowledge(key, value, float(i))


def test_restore_keeps_the_knowledge_base_declaration_and_converts_to_it():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "v", [1, 2, 3])
        kb = KnowledgeBase()
        kb.declare("v", "float", history=2)  # the application changed int to float
        with SqliteStorage(path) as storage:
            assert storage.restore(kb) == 2
        assert kb.history("v") == [Sample(1.0, 2.0), Sample(2.0, 3.0)]
        assert all(type(s.value) is float for s in kb.history("v"))


def test_restore_skips_samples_that_no_longer_fit_with_a_warning(caplog):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "v", [-1.5, 2.5, -0.5, 3.5])
        kb = KnowledgeBase()
        kb.declare("v", "float", minimum=0)  # the application added a bound
        with caplog.at_level(logging.WARNING, logger="rasm.knowledge"):
            with SqliteStorage(path) as storage:
                assert storage.restore(kb) == 2
        assert kb.history("v") == [Sample(1.0, 2.5), Sample(3.0, 3.5)]
        assert "skipped 2 stored sample(s) of 'v'" in caplog.text
        assert "below the declared minimum" in caplog.text  # worded as Telegraf words it


def test_a_strict_restore_refuses_samples_that_do_not_fit_and_loads_nothing():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "a", [1.0])
        _file_with(path, "v", [1.5, 2.5])
        kb = KnowledgeBase()
        kb.declare("v", "int")
        with SqliteStorage(path) as storage:
            with pytest.raises(KnowledgeError, match="cannot restore 'v' from .*expected int"):
                storage.restore(kb, strict=True)
        assert kb.read_sample("a") is None and kb.read_sample("v") is None


def test_a_hand_damaged_file_is_reported_not_loaded():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "v", [1.5, 2.5])
        with sqlite3.connect(path) as db:
            db.execute("""UPDATE batches SET "values" = '[1.5, {oops' WHERE key = 'v'""")
        kb = KnowledgeBase()
        with SqliteStorage(path) as storage:
            with pytest.raises(KnowledgeError, match="k.db is damaged: key 'v'"):
                storage.restore(kb)
        assert kb.read_sample("v") is None


def test_a_batch_whose_times_and_values_disagree_is_reported_not_loaded(tmp_path):
    path = tmp_path / "k.db"
    _file_with(path, "v", [1.5, 2.5])
    with sqlite3.connect(path) as db:
        db.execute("""UPDATE batches SET times = '[0.0]' WHERE key = 'v'""")
    kb = KnowledgeBase()
    with SqliteStorage(path) as storage:
        with pytest.raises(KnowledgeError, match=r"k.db is damaged: key 'v': 1 times for 2 values"):
            storage.restore(kb)


SCHEMA_1 = """
CREATE TABLE declarations (key TEXT PRIMARY KEY, type TEXT NOT NULL, history INTEGER NOT NULL,
                           minimum TEXT, maximum TEXT);
CREATE TABLE samples (seq INTEGER PRIMARY KEY, key TEXT NOT NULL, time REAL NOT NULL,
                      type TEXT NOT NULL, value TEXT NOT NULL);
CREATE INDEX samples_by_key ON samples (key, seq);
PRAGMA user_version = 1;
"""


def test_a_file_of_schema_1_is_converted_and_restores_every_sample(tmp_path):
    # what an earlier rasm wrote: one row per sample, each value its own JSON text
    path = tmp_path / "k.db"
    with sqlite3.connect(path) as db:
        db.executescript(SCHEMA_1)
        db.execute("INSERT INTO declarations VALUES ('t', 'float', 5, NULL, NULL)")
        db.executemany(
            "INSERT INTO samples (key, time, type, value) VALUES (?, ?, ?, ?)",
            [("t", 0.5, "float", "NaN"), ("s", 0.75, "str", '"a, b"'), ("t", 1.0, "float", "2.5"),
             ("n", 1.0, "int", str(2**70))],
        )
    back = restored(path)
    assert math.isnan(back.history("t")[0].value) and back.history("t")[1] == Sample(1.0, 2.5)
    assert back.declaration("t") == Declaration("t", "float", 5)
    assert back.history("s") == [Sample(0.75, "a, b")]
    assert back.history("n") == [Sample(1.0, 2**70)]
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA user_version").fetchone()[0] == 2
        tables = {name for (name,) in db.execute("SELECT name FROM sqlite_master")}
    assert "samples" not in tables and "batches" in tables


def test_a_damaged_file_of_schema_1_is_reported_and_left_as_it_was(tmp_path):
    path = tmp_path / "k.db"
    with sqlite3.connect(path) as db:
        db.executescript(SCHEMA_1)
        db.execute(
            "INSERT INTO samples (key, time, type, value) VALUES ('t', 0.5, 'float', '{oops')"
        )
    with pytest.raises(KnowledgeError, match=r"k.db is damaged: key 't'"):
        SqliteStorage(path)
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA user_version").fetchone()[0] == 1
        assert db.execute("SELECT count(*) FROM samples").fetchone()[0] == 1


def test_a_file_of_another_schema_version_is_refused(tmp_path):
    path = tmp_path / "k.db"
    SqliteStorage(path).close()
    with sqlite3.connect(path) as db:
        db.execute("PRAGMA user_version = 7")
    with pytest.raises(
        KnowledgeError, match=r"not a rasm knowledge file of schema 2 \(user_version 7\)"
    ):
        SqliteStorage(path)


def test_restore_refuses_a_knowledge_base_that_already_holds_samples():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "v", [1.5])
        kb = KnowledgeBase()
        kb.register_knowledge("v", 9.5, 100.0)
        with SqliteStorage(path) as storage:
            with pytest.raises(KnowledgeError, match="already holds samples of it"):
                storage.restore(kb)


def test_restored_samples_are_not_written_again():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        _file_with(path, "v", [1.5, 2.5])
        kb = KnowledgeBase()
        with SqliteStorage(path) as storage:
            storage.attach(kb)  # attached before restore: restore must still not re-buffer
            storage.restore(kb)
            assert storage.update_persistency() == 0
            kb.register_knowledge("v", 3.5, 5.0)
            assert storage.update_persistency() == 1
        assert [t for t, _ in rows(path, "v")] == [0.0, 1.0, 5.0]


# -- files that are not ours, and one writer per file ---------------------------------------------


def test_a_file_that_is_not_a_database_is_refused(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("this is not SQLite\n" * 100)
    with pytest.raises(KnowledgeError, match="notes.txt is not a rasm knowledge file"):
        SqliteStorage(path)


def test_another_applications_database_is_refused(tmp_path):
    path = tmp_path / "other.db"
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE customers (name TEXT)")
    with pytest.raises(KnowledgeError, match="not a rasm knowledge file of schema 2"):
        SqliteStorage(path)
    with sqlite3.connect(path) as db:  # untouched
        assert [r[0] for r in db.execute("SELECT name FROM sqlite_master")] == ["customers"]


def test_one_storage_at_a_time_writes_a_file(tmp_path):
    path = tmp_path / "k.db"
    first = SqliteStorage(path)
    with pytest.raises(KnowledgeError, match=f"in use by pid {os.getpid()} "):
        SqliteStorage(path)
    first.close()
    SqliteStorage(path).close()  # free again once closed


def test_a_missing_folder_is_a_knowledge_error(tmp_path):
    with pytest.raises(KnowledgeError, match="knowledge store .* failed: creating its lock"):
        SqliteStorage(tmp_path / "missing" / "k.db")


# -- threads --------------------------------------------------------------------------------------


def test_writers_and_a_flusher_in_parallel_persist_every_sample_once(tmp_path):
    path = tmp_path / "k.db"
    threads, per_thread = 4, 1500
    kb = KnowledgeBase(default_history=per_thread)
    start = threading.Barrier(threads + 1)
    writers_done = threading.Event()
    flushed = [0]
    with SqliteStorage(path, keep=per_thread) as storage:
        storage.attach(kb)

        def write(t: int) -> None:
            start.wait()
            for i in range(per_thread):
                kb.register_knowledge(f"k{t}", i, float(i))

        def flush() -> None:
            start.wait()
            while not writers_done.is_set():
                flushed[0] += storage.update_persistency()

        workers = [threading.Thread(target=write, args=(t,)) for t in range(threads)]
        flusher = threading.Thread(target=flush)
        for thread in [*workers, flusher]:
            thread.start()
        for thread in workers:
            thread.join(60)
        writers_done.set()
        flusher.join(60)
        flushed[0] += storage.update_persistency()
    assert flushed[0] == threads * per_thread
    back = restored(path)
    for t in range(threads):
        assert [s.value for s in back.history(f"k{t}")] == list(range(per_thread))


@pytest.mark.slow
@SETTINGS
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=20))
def test_persisted_times_come_back_exactly(times):
    times = sorted(times)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.db"
        kb = KnowledgeBase()
        kb.declare("k", "int", history=50)
        with SqliteStorage(path) as storage:
            storage.attach(kb)
            for i, time in enumerate(times):
                kb.register_knowledge("k", i, time)
        assert [s.time for s in restored(path).history("k")] == times
