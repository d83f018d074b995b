"""Where failing examples are saved, so that a failure found by a test can be replayed by hand.

Two kinds of file are saved, both under :func:`failures_dir` (``.rasm/failures`` in the working
directory unless ``RASM_FAILURES`` or the pytest option ``--rasm-failures`` says otherwise):

* ``<chart>-<hash>.jsonl``: an events file, replayed with ``rasm simulate CHART --events FILE``;
* ``<props>-<hash>.jsonl``: a trace, checked with ``rasm check PROPS FILE``.

The hash is that of the file's content without the stages' measured ``duration`` values (wall
time, different on every run), so the same failure found twice — a seeded run again — is one
file, with the same name every time. Inside a
hypothesis test a file is written only for the example hypothesis finally reports (the shortest
it found), not for every failing example it tries while shrinking.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from rasm.loop import MEASURED_KEYS

__all__ = ["failures_dir", "is_final_example", "save_jsonl", "saved_files"]

_ENVIRONMENT = "RASM_FAILURES"
_saved: list[Path] = []


def failures_dir() -> Path:
    """The folder failures are saved in: ``$RASM_FAILURES`` or ``.rasm/failures``."""
    return Path(os.environ.get(_ENVIRONMENT) or Path(".rasm") / "failures")


def is_final_example() -> bool:
    """False while hypothesis is still searching or shrinking; True otherwise.

    Outside a hypothesis test every call is "final". Inside one, only the replay of the example
    hypothesis reports is.
    """
    from hypothesis.control import current_build_context, currently_in_test_context

    if not currently_in_test_context():
        return True
    return bool(getattr(current_build_context(), "is_final", True))


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "failure"


def save_jsonl(stem: str, lines: Iterable[Mapping[str, Any]]) -> Path:
    """Write ``lines`` as JSON lines to ``<failures dir>/<stem>-<hash>.jsonl``; return the path.
    The hash leaves out what the wall clock measures (MEASURED_KEYS): a seed names its file."""
    records = [dict(line) for line in lines]
    text = "".join(json.dumps(record) + "\n" for record in records)
    timeless = "".join(
        json.dumps({k: v for k, v in r.items() if k not in MEASURED_KEYS}) + "\n"
        for r in records
    )
    digest = hashlib.sha256(timeless.encode("utf-8")).hexdigest()[:10]
    folder = failures_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{_slug(stem)}-{digest}.jsonl"
    path.write_text(text, encoding="utf-8")
    if path not in _saved:
        _saved.append(path)
    return path


def saved_files() -> list[Path]:
    """Every file saved by this process, oldest first (the pytest plugin lists them at the end)."""
    return list(_saved)
