"""open_knowledge: the manifest's knowledge: field."""

from __future__ import annotations

import os

import pytest

from rasm.knowledge import KnowledgeBase, KnowledgeError, SqliteStorage, open_knowledge


def test_memory_has_no_storage():
    kb, storage = open_knowledge("memory")
    assert isinstance(kb, KnowledgeBase) and storage is None


def test_sqlite_path_is_relative_to_the_app_folder_and_restored_on_reopen(tmp_path):
    kb, storage = open_knowledge("sqlite:state/knowledge.db", base_dir=tmp_path)
    try:
        assert isinstance(storage, SqliteStorage)
        assert storage.path == tmp_path / "state" / "knowledge.db"  # folder created
        kb.declare("velocity", "float", history=10)
        kb.register_knowledge("velocity", 0.3, 1.0)  # attached: buffered without a call
    finally:
        storage.close()
    kb, storage = open_knowledge("sqlite:state/knowledge.db", base_dir=tmp_path)
    try:
        assert kb.read_knowledge("velocity") == 0.3
        assert kb.declaration("velocity").history == 10
        kb.register_knowledge("velocity", 0.4, 2.0)
        assert storage.update_persistency() == 1
    finally:
        storage.close()


def test_an_absolute_sqlite_path_ignores_the_base_folder(tmp_path):
    path = tmp_path / "abs.db"
    kb, storage = open_knowledge(f"sqlite:{path}", base_dir="/nonexistent")
    storage.close()
    assert storage.path == path and path.exists()


def test_a_relative_path_without_base_folder_is_taken_from_the_current_one(tmp_path):
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        _, storage = open_knowledge("sqlite:k.db")
        storage.close()
    finally:
        os.chdir(here)
    assert (tmp_path / "k.db").exists()


def test_an_unreachable_redis_is_a_clear_error():
    # port 1 on loopback: nothing listens there (the Redis store itself: test_redis.py)
    with pytest.raises(KnowledgeError, match="cannot reach the Redis knowledge store"):
        open_knowledge("redis://127.0.0.1:1/0")


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("mongodb://db", "unknown knowledge store 'mongodb://db': expected memory, sqlite:PATH"),
        ("", "unknown knowledge store ''"),
        ("disk", "unknown knowledge store 'disk'"),
        ("sqlite:", "names no file: write sqlite:PATH"),
        ("sqlite:///tmp/x.db", "write sqlite:PATH .* without //"),
        (42, "knowledge store must be text"),
    ],
)
def test_anything_else_is_refused_with_the_forms_that_work(url, message):
    with pytest.raises(KnowledgeError, match=message):
        open_knowledge(url)


def test_a_file_in_use_is_refused_and_the_first_user_keeps_it(tmp_path):
    _, first = open_knowledge("sqlite:k.db", base_dir=tmp_path)
    try:
        with pytest.raises(KnowledgeError, match=f"in use by pid {os.getpid()} "):
            open_knowledge("sqlite:k.db", base_dir=tmp_path)
        # a fresh open waits for the lock too: it never deletes a file another run has open
        with pytest.raises(KnowledgeError, match="in use by pid"):
            open_knowledge("sqlite:k.db", base_dir=tmp_path, fresh=True)
        assert (tmp_path / "k.db").exists()
    finally:
        first.close()


def test_a_fresh_open_starts_empty_and_a_plain_one_restores(tmp_path):
    kb, storage = open_knowledge("sqlite:k.db", base_dir=tmp_path)
    kb.declare("x", "float")
    kb.register_knowledge("x", 1.0, 1.0)
    storage.close()
    kb, storage = open_knowledge("sqlite:k.db", base_dir=tmp_path)
    storage.close()
    assert kb.read_knowledge("x") == 1.0
    kb, storage = open_knowledge("sqlite:k.db", base_dir=tmp_path, fresh=True)
    storage.close()
    assert list(kb.keys()) == []
    kb, storage = open_knowledge("sqlite:k.db", base_dir=tmp_path)
    storage.close()
    assert list(kb.keys()) == []
