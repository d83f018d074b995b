"""Where a run keeps its state: one folder per app, never shared by two apps or two runs."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap

from rich.console import Console

from rasm import Platform, RunOptions
from rasm.cli.console import LiveView
from rasm.platform.manifest import load_manifest
from rasm.times import format_seconds

from .conftest import HOTBOX


def copy_hotbox(folder):
    shutil.copytree(HOTBOX, folder, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    return folder


def test_two_apps_of_the_same_name_keep_their_knowledge_apart(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    first, second = copy_hotbox(tmp_path / "a" / "hotbox"), copy_hotbox(tmp_path / "b" / "hotbox")
    Platform(load_manifest(first), RunOptions(clock="simulated", seed=1)).run(2)
    Platform(load_manifest(second), RunOptions(clock="simulated", seed=1)).run(2)
    folders = sorted(p.name for p in (tmp_path / ".rasm").iterdir())
    assert folders[0] == "hotbox" and len(folders) == 2 and folders[1].startswith("hotbox-")
    for name, app in zip(folders, (first, second), strict=True):
        claim = (tmp_path / ".rasm" / name / "app").read_text().strip()
        assert claim == str(app.resolve())
        assert (tmp_path / ".rasm" / name / "simulated.sqlite").is_file()
    # each app finds its own folder again on its next run
    assert Platform(load_manifest(second), RunOptions(
        clock="simulated",
    )).state_dir.name == folders[1]
    assert Platform(load_manifest(first), RunOptions(clock="simulated")).state_dir.name == "hotbox"


HOLD = textwrap.dedent(
    """
    import sys
    from rasm.knowledge import open_knowledge
    kb, storage = open_knowledge(sys.argv[1])
    print("holding", flush=True)
    sys.stdin.read()  # until the test closes our stdin
    storage.close()
    """
)


def test_a_second_run_on_a_store_in_use_names_the_process_and_leaves_the_store_alone(tmp_path):
    store = tmp_path / ".rasm" / "hotbox" / "simulated.sqlite"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, f"sqlite:{store}"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "holding"
        run = subprocess.run(
            [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--clock", "simulated",
             "--duration", "2"],
            capture_output=True, text=True, timeout=120, cwd=tmp_path,
        )
        assert store.is_file()  # the simulated run did not delete a file in use
    finally:
        holder.stdin.close()
        holder.wait(30)
    assert run.returncode == 2, run.stdout + run.stderr
    assert f"is in use by pid {holder.pid} (another rasm run of this app)" in run.stderr
    assert "disk I/O error" not in run.stderr and "Traceback" not in run.stderr


def test_a_live_run_says_its_timeline_continues_the_persisted_one(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    manifest = load_manifest(HOTBOX)
    first = Platform(manifest, RunOptions(clock="wall", seed=1))
    assert first.restored_from is None
    first.run(0.6)
    second = Platform(load_manifest(HOTBOX), RunOptions(clock="wall", seed=1))
    second.run(0.3)
    assert second.restored_from == "sqlite:.rasm/hotbox/knowledge.sqlite"
    assert 0 < second.timeline_start <= 0.6 + 0.1
    console = Console(record=True, width=200)
    view = LiveView(second, console, duration=40)
    console.print(view.render(second.timeline_start + 1.5))
    text = console.export_text()
    assert "t=   1.50s / 40s" in text  # the time of this run, not of the timeline
    assert "timeline continued from sqlite:.rasm/hotbox/knowledge.sqlite" in text
    assert f"trace times start at {format_seconds(second.timeline_start)} s" in text
