"""The Storage Manager persists knowledge updates in batches, a flush period after the first."""

from __future__ import annotations

import sqlite3
from pathlib import Path

from sismic.clock import SimulatedClock

from rasm.knowledge import open_knowledge
from rasm.platform import Platform
from rasm.platform.run_options import RunOptions
from rasm.platform.storage_manager import StorageManager

from .conftest import HOTBOX


def test_updates_are_persisted_together_a_flush_period_after_the_first(tmp_path: Path) -> None:
    url = f"sqlite:{tmp_path / 'knowledge.sqlite'}"
    kb, storage = open_knowledge(url, base_dir=tmp_path)
    storage.detach()  # the block feeds the storage, as the platform wires it
    clock = SimulatedClock()
    stom = StorageManager(storage, flush_period=1.0, clock=clock)
    kb.subscribe(stom.register_knowledge_update)
    wake_ups: list[float] = []
    stom.on_deadline = lambda block, due: wake_ups.append(due)
    stom.send("configure")
    assert "idle" in stom.configuration
    for i in range(5):
        kb.register_knowledge("speed", float(i), i / 10)
    # the first update made the chart dirty and asked to be woken once; none is written yet
    assert "dirty" in stom.configuration and wake_ups == [1.0] and stom.persisted == 0
    clock.time = 1.0
    stom.wake()
    assert stom.persisted == 5 and "idle" in stom.configuration
    kb.register_knowledge("speed", 9.0, 2.0)  # a new batch: written at termination
    stom.send("terminate")
    restored, again = open_knowledge(url, base_dir=tmp_path)
    try:
        assert [s.value for s in restored.history("speed")] == [0.0, 1.0, 2.0, 3.0, 4.0, 9.0]
    finally:
        again.close()


def test_without_storage_updates_are_ignored() -> None:
    stom = StorageManager(None)
    stom.send("configure")
    stom.register_knowledge_update("speed", None)  # nothing to buffer into, nothing stepped
    assert "idle" in stom.configuration and stom.update_persistency() == 0


def test_a_simulated_run_flushes_every_ten_simulated_seconds(tmp_path: Path) -> None:
    # the next simulated run starts the file afresh and ten simulated seconds pass in
    # milliseconds: a flush each simulated second would be work no crash needs
    path = tmp_path / "knowledge.sqlite"
    platform = Platform(HOTBOX, RunOptions(
        clock="simulated",
        seed=1,
        knowledge=f"sqlite:{path}",
        state_dir=tmp_path,
    ))
    platform.run(35.0)
    with sqlite3.connect(path) as db:
        flushed_at = [last for (last,) in db.execute(
            "SELECT last FROM batches WHERE key = 'temperature' ORDER BY seq"
        )]
    assert len(flushed_at) == 4  # after 10, 20 and 30 s, then the rest at the end
    gaps = [later - earlier for earlier, later in zip(flushed_at, flushed_at[1:], strict=False)]
    assert all(abs(gap - 10.0) < 0.5 for gap in gaps[:-1]), flushed_at
