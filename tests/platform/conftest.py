"""Shared helpers for runtime tests: the Hotbox manifest and reading traces."""

from __future__ import annotations

import json
import os
import subprocess
import sys
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


def start_managed(broker, cwd: Path, *, duration: float, env: dict | None = None):
    """The Hotbox's managed system (its simulator) in a process of its own, over ``broker``."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rasm.cli",
            "run",
            str(HOTBOX),
            "--role",
            "managed",
            "--transport",
            broker.url,
            "--duration",
            str(duration),
        ],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, **(env or {})},
    )
