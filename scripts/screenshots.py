"""Take the documentation's screenshots of ``rasm report`` and ``rasm run --dashboard``.

    .venv/bin/python scripts/screenshots.py [OUT_DIR]      # default: docs/images

Uses the same headless Debian chromium (``/usr/bin/chromium``, driven by Playwright) as the
tests. Writes:

- ``report.png``: the report of a 40 s simulated Hotbox run (seed 1) with its properties;
- ``report-focus.png``: the timelines after clicking the second adaptation in the table;
- ``dashboard.png``: the live dashboard of a wall-clock Hotbox run, once it has adapted.
"""

from __future__ import annotations

import sys
import tempfile
import threading
from pathlib import Path

from playwright.sync_api import sync_playwright

from rasm import Platform, RunOptions
from rasm.platform.manifest import load_manifest
from rasm.report import write_report
from rasm.report.dashboard import serve

ROOT = Path(__file__).resolve().parents[1]
HOTBOX = ROOT / "examples" / "hotbox"
CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
VIEWPORT = {"width": 1280, "height": 900}


def report(browser, out: Path, work: Path) -> None:
    trace = work / "hotbox.jsonl"
    Platform(
        load_manifest(HOTBOX), RunOptions(clock="simulated", seed=1, trace=trace,
                                          knowledge="memory")
    ).run(40)
    page_file = work / "report.html"
    write_report(trace, page_file, [HOTBOX / "properties" / "hotbox.rv"], title="rasm report: "
                 "Hotbox, 40 s simulated (seed 1)")
    page = browser.new_page(viewport=VIEWPORT)
    page.goto(page_file.as_uri())
    page.wait_for_selector("body[data-rendered=true]")
    page.screenshot(path=str(out / "report.png"), full_page=True)
    link = page.locator("#adaptation-2 a.goto")
    link.click()
    page.wait_for_selector(f"body[data-focus='{link.get_attribute('data-time')}']")
    page.locator("#timelines").scroll_into_view_if_needed()
    page.locator("#timelines").screenshot(path=str(out / "report-focus.png"))
    page.close()


def dashboard(browser, out: Path) -> None:
    platform = Platform(
        load_manifest(HOTBOX),
        RunOptions(clock="wall", seed=1, knowledge="memory", scenario={"openings": [[0.3, 3.0]]}),
    )
    platform.build()
    server = serve(platform, 0)
    runner = threading.Thread(target=platform.run, args=(120.0,), daemon=True)
    page = browser.new_page(viewport={"width": 1280, "height": 1700})
    try:
        page.goto(server.url)
        page.wait_for_selector("body[data-rendered=true]")
        runner.start()
        page.wait_for_function(
            "Number(document.getElementById('count-executed').textContent) >= 1",
            timeout=120_000,
        )
        # a few more iterations after the adaptation, so the timelines show it
        records = int(page.evaluate("document.body.dataset.records"))
        page.wait_for_function(
            f"Number(document.body.dataset.records) > {records + 60}", timeout=60_000
        )
        page.screenshot(path=str(out / "dashboard.png"))
    finally:
        platform.scheduler.stop()
        runner.join(30)
        server.close()
        page.close()


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else ROOT / "docs" / "images"
    out.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as playwright, tempfile.TemporaryDirectory() as work:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            report(browser, out, Path(work))
            dashboard(browser, out)
        finally:
            browser.close()
    for name in ("report.png", "report-focus.png", "dashboard.png"):
        print(out / name)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
