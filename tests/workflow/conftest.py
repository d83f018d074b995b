"""Every packaging in these tests uses the session's wheelhouse (tests/conftest.py), the one the
workflow guide's commands use too."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session", autouse=True)
def shared_wheelhouse(wheelhouse: Path) -> Path:
    return wheelhouse
