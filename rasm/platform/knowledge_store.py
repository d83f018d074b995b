"""The app's knowledge store, opened for a run: where it lives, what it restored, and the
signals declared in it.

``sqlite`` in the manifest (or ``--knowledge``) means a file in the app's state folder:
``simulated.sqlite`` for a simulated run, ``knowledge.sqlite`` for a live one. A simulation is a
fresh world (nothing from an earlier run); a live run restores what was stored and continues
its timeline after the newest sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rasm.errors import PlatformError
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.storage import Storage
from rasm.losses import describe_error
from rasm.platform.manifest import AppManifest
from rasm.platform.state_dir import claim_state_dir

__all__ = ["AppKnowledge", "open_app_knowledge"]


@dataclass(frozen=True)
class AppKnowledge:
    """An opened knowledge store and what the run takes from it."""

    store: KnowledgeBase
    storage: Storage | None  # the persistent storage the Storage Manager feeds, if any
    restored_from: str | None  # the store a live run's timeline continues from (None: none)
    timeline_start: float  # the newest sample restored (0 when nothing was)


def open_app_knowledge(
    manifest: AppManifest, url: str, *, state_dir: Path, simulated: bool, claim: bool
) -> AppKnowledge:
    """Open (and restore) the knowledge store ``url`` names, with the app's signals declared.

    ``claim``: the state folder is the default one, marked as this app's when a SQLite file
    goes in it (:func:`rasm.platform.state_dir.claim_state_dir`).
    """
    from rasm.knowledge import open_knowledge

    opened = url
    if url == "sqlite":
        name = "simulated.sqlite" if simulated else "knowledge.sqlite"
        opened = f"sqlite:{state_dir / name}"
        if claim:
            try:
                claim_state_dir(state_dir, manifest)
            except OSError as exc:
                raise PlatformError(
                    f"creating the state folder {state_dir} (the knowledge store and the timing "
                    f"file go there) failed: {describe_error(exc)}; run from a folder rasm may "
                    "write to, or give the app another store (knowledge: memory or "
                    "sqlite:PATH) and timing (timing: off or file:PATH)"
                ) from None
    store, storage = open_knowledge(opened, base_dir=Path.cwd(), fresh=simulated)
    if opened.startswith(("redis://", "rediss://")) and simulated:
        store.clear()  # a simulation is a fresh world here too
    if storage is not None:
        storage.detach()  # the Storage Manager block feeds it (and steps its chart)
    samples = [store.read_sample(key) for key in store.keys()]
    restored = [sample for sample in samples if sample is not None]
    for signal in manifest.signals.values():
        store.declare(
            signal.key,
            signal.type,
            history=signal.history,
            minimum=signal.minimum,
            maximum=signal.maximum,
        )
    return AppKnowledge(
        store=store,
        storage=storage,
        restored_from=opened if restored else None,
        timeline_start=max((sample.time for sample in restored), default=0.0),
    )
