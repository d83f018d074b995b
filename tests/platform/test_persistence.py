"""Knowledge survives a managing system killed with SIGKILL (real process, real SQLite file)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from rasm.knowledge import open_knowledge

from .conftest import HOTBOX


@pytest.mark.slow
def test_knowledge_survives_sigkill_and_comes_back_on_restart(tmp_path):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    child = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--duration", "60", "--trace", "-"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    seen = []
    try:
        for line in child.stdout:  # blocks on the pipe: no polling
            record = json.loads(line)
            if "temperature" in record:
                seen.append((record["time"], record["temperature"]))
            if record["time"] >= 3.5:  # the Storage Manager flushes every second
                break
        child.send_signal(signal.SIGKILL)
    finally:
        child.wait(10)
    assert child.returncode == -signal.SIGKILL
    kb, storage = open_knowledge(f"sqlite:{tmp_path / '.rasm' / 'hotbox' / 'knowledge.sqlite'}")
    try:
        restored = [(s.time, s.value) for s in kb.history("temperature")]
    finally:
        storage.close()
    # at least two seconds were persisted, and what came back is exactly a prefix of what the
    # managing system saw: nothing invented, nothing reordered
    assert restored and restored[-1][0] >= 1.5
    assert len(restored) <= len(seen)
    for (t_restored, v_restored), (t_seen, v_seen) in zip(restored, seen, strict=False):
        assert abs(t_restored - t_seen) < 1e-6 and v_restored == v_seen
