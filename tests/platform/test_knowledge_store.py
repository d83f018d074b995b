"""Opening an app's knowledge store for a run: fresh for a simulation, restored for a live run."""

from __future__ import annotations

import pytest

from rasm.errors import KnowledgeError
from rasm.platform.knowledge_store import open_app_knowledge
from rasm.platform.manifest import load_manifest

from .conftest import HOTBOX


def stored_before(state_dir, samples):
    """A live run's knowledge file holding ``samples`` ({key: (value, time)}), closed (the
    storage is fed as the Storage Manager feeds it)."""
    opened = open_app_knowledge(
        load_manifest(HOTBOX), "sqlite", state_dir=state_dir, simulated=False, claim=False
    )
    for key, (value, time) in samples.items():
        opened.storage.buffer(key, opened.store.register_knowledge(key, value, time))
    opened.storage.update_persistency()
    opened.storage.close()


def test_a_live_run_restores_the_store_and_continues_after_its_newest_sample(tmp_path):
    stored_before(tmp_path, {"temperature": (21.5, 3.0), "heater_power": (0.4, 7.5)})
    opened = open_app_knowledge(
        load_manifest(HOTBOX), "sqlite", state_dir=tmp_path, simulated=False, claim=False
    )
    try:
        assert opened.restored_from == f"sqlite:{tmp_path / 'knowledge.sqlite'}"
        assert opened.timeline_start == 7.5
        assert opened.store.read_knowledge("temperature") == 21.5
    finally:
        opened.storage.close()


def test_a_simulation_starts_from_nothing_whatever_its_file_held(tmp_path):
    manifest = load_manifest(HOTBOX)
    first = open_app_knowledge(manifest, "sqlite", state_dir=tmp_path, simulated=True, claim=False)
    first.storage.buffer("temperature", first.store.register_knowledge("temperature", 30.0, 4.0))
    first.storage.update_persistency()
    first.storage.close()
    again = open_app_knowledge(manifest, "sqlite", state_dir=tmp_path, simulated=True, claim=False)
    try:
        assert (again.restored_from, again.timeline_start) == (None, 0.0)
        assert again.store.read_knowledge("temperature") is None
        assert (tmp_path / "simulated.sqlite").is_file()
        assert not (tmp_path / "knowledge.sqlite").exists()
    finally:
        again.storage.close()


def test_the_apps_signals_are_declared_with_their_bounds(tmp_path):
    opened = open_app_knowledge(
        load_manifest(HOTBOX), "memory", state_dir=tmp_path, simulated=True, claim=True
    )
    assert opened.storage is None and opened.restored_from is None
    with pytest.raises(KnowledgeError):  # temperature: {type: float, min: -40, max: 150}
        opened.store.register_knowledge("temperature", 151.0, 1.0)
    with pytest.raises(KnowledgeError):
        opened.store.register_knowledge("temperature", "hot", 1.0)
    opened.store.register_knowledge("temperature", 150.0, 1.0)
    assert not any(tmp_path.iterdir())  # only a SQLite file claims the state folder


def test_the_default_state_folder_is_claimed_for_the_app_when_its_file_goes_there(tmp_path):
    manifest = load_manifest(HOTBOX)
    opened = open_app_knowledge(manifest, "sqlite", state_dir=tmp_path, simulated=True, claim=True)
    opened.storage.close()
    assert (tmp_path / "app").read_text().strip() == str(manifest.folder.resolve())
