"""Shared helpers for the workflow tests: model text, positions, a clean module cache."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HOTBOX_MODEL = ROOT / "examples" / "models" / "hotbox.yaml"


def position(text: str, needle: str, occurrence: int = 1) -> tuple[int, int]:
    """1-based line and column where the ``occurrence``-th ``needle`` starts in ``text``."""
    start = -1
    for _ in range(occurrence):
        start = text.index(needle, start + 1)
    line = text.count("\n", 0, start) + 1
    col = start - (text.rfind("\n", 0, start) + 1) + 1
    return line, col


def forget_apps() -> None:
    """Drop app modules the platform cached, so the next load reads the files again."""
    for name in [n for n in sys.modules if n.startswith("rasm_app_")]:
        del sys.modules[name]
