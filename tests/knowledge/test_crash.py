"""A killed process (SIGKILL) loses at most what it had not persisted: real child processes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from rasm.knowledge import KnowledgeBase, SqliteStorage

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")


def child(code: str) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )


def read_line(process: subprocess.Popen[str]) -> str:
    line = process.stdout.readline()  # blocks until the child says so: no sleeping
    assert line, f"child ended early with code {process.wait()}"
    return line.strip()


def kill(process: subprocess.Popen[str]) -> None:
    process.send_signal(signal.SIGKILL)
    assert process.wait(30) == -signal.SIGKILL
    process.stdout.close()
    process.stdin.close()


def restore(path: Path) -> KnowledgeBase:
    kb = KnowledgeBase()
    with SqliteStorage(path) as storage:
        storage.restore(kb)
    return kb


def test_kill_9_loses_exactly_what_was_not_persisted(tmp_path):
    path = tmp_path / "k.db"
    process = child(
        f"""
        import sys
        from rasm.knowledge import KnowledgeBase, SqliteStorage
        kb = KnowledgeBase()
        storage = SqliteStorage({str(path)!r})
        storage.restore(kb)
        storage.attach(kb)
        kb.declare("x", "int", history=500)
        for i in range(50):
            kb.register_knowledge("x", i, float(i))
            kb.register_knowledge("plan", {{"step": i, "path": [i, i + 1]}}, float(i))
        print(storage.update_persistency(), flush=True)
        for i in range(50, 80):  # registered, buffered, never persisted
            kb.register_knowledge("x", i, float(i))
            kb.register_knowledge("plan", {{"step": i}}, float(i))
        print("unpersisted", kb.read_knowledge("x"), flush=True)
        sys.stdin.read()  # wait here until killed
        """
    )
    try:
        assert read_line(process) == "100"
        assert read_line(process) == "unpersisted 79"
    finally:
        kill(process)
    kb = restore(path)
    assert [s.value for s in kb.history("x")] == list(range(50))
    assert [s.value for s in kb.history("plan")] == [
        {"step": i, "path": [i, i + 1]} for i in range(50)
    ]
    assert kb.declaration("x").history == 500


def test_a_kill_during_flushes_leaves_whole_transactions_only(tmp_path):
    path = tmp_path / "k.db"
    batch = 200
    process = child(
        f"""
        from rasm.knowledge import KnowledgeBase, SqliteStorage
        kb = KnowledgeBase(default_history=100000)
        storage = SqliteStorage({str(path)!r}, keep=100000)
        storage.attach(kb)
        i = 0
        while True:  # flush after flush until killed, possibly inside a transaction
            for _ in range({batch}):
                kb.register_knowledge("x", i, float(i))
                i += 1
            storage.update_persistency()
            print(i, flush=True)
        """
    )
    try:
        for _ in range(3):
            persisted = int(read_line(process))
    finally:
        kill(process)
    values = [s.value for s in restore(path).history("x")]
    assert len(values) >= persisted  # everything reported as persisted survived
    assert len(values) % batch == 0  # and no transaction was cut in half
    assert values == list(range(len(values)))
