"""Shared fixtures: failures go to a temporary folder, never into the repository."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HOTBOX = ROOT / "examples" / "hotbox"
HOTBOX_PROPS = HOTBOX / "properties" / "hotbox.rv"


@pytest.fixture(scope="session", autouse=True)
def failures_folder(tmp_path_factory):
    """Point RASM_FAILURES at a temporary folder for the whole session (restored after)."""
    folder = tmp_path_factory.mktemp("rasm-failures")
    before = os.environ.get("RASM_FAILURES")
    os.environ["RASM_FAILURES"] = str(folder)
    yield folder
    if before is None:
        os.environ.pop("RASM_FAILURES", None)
    else:
        os.environ["RASM_FAILURES"] = before
