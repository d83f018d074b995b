"""Shared helpers for runtime tests: the Hotbox manifest and reading traces."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rasm.platform.manifest import load_manifest

ROOT = Path(__file__).resolve().parents[2]
HOTBOX = ROOT / "examples" / "hotbox"


@pytest.fixture
def hotbox():
    return load_manifest(HOTBOX)


def read_trace(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
