"""Fixtures for the report and dashboard tests: a Hotbox trace and a real headless chromium.

The browser tests drive Debian's ``chromium`` (``/usr/bin/chromium``) through Playwright; they
skip, saying why, only when that browser is not installed.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rasm import Platform, RunOptions
from rasm.platform.manifest import load_manifest

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ROOT = Path(__file__).resolve().parents[2]
HOTBOX = ROOT / "examples" / "hotbox"


@pytest.fixture(scope="session")
def hotbox_trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 40 s simulated Hotbox run's adaptation trace (three adaptations)."""
    path = tmp_path_factory.mktemp("hotbox") / "hotbox.jsonl"
    platform = Platform(
        load_manifest(HOTBOX), RunOptions(clock="simulated", seed=1, trace=path, knowledge="memory")
    )
    summary = platform.run(40)
    assert summary.stats.executed >= 1
    return path


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """Headless chromium (a fresh profile: Playwright gives each launch its own)."""
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is not installed (Debian package: chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


class Page:
    """A browser page that records console errors and uncaught exceptions."""

    def __init__(self, page: Any) -> None:
        self.page = page
        self.errors: list[str] = []
        page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(f"uncaught: {e}"))


@pytest.fixture
def page(browser: Any) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1300, "height": 900})
    recorded = Page(context.new_page())
    yield recorded
    context.close()
