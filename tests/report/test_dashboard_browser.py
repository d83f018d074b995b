"""``rasm run --dashboard``: the views follow a wall-clock Hotbox run in a real browser."""

from __future__ import annotations

import json
import socket
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from rasm import Platform, RunOptions
from rasm.errors import PlatformError
from rasm.platform.manifest import load_manifest
from rasm.report.dashboard import serve

from .conftest import HOTBOX

# the lid opens at 0.3 s for 3 s: the loop adapts (boost) about 2 s later, in wall time
SCENARIO = {"openings": [[0.3, 3.0]]}


def _hotbox(clock: str = "wall") -> Platform:
    platform = Platform(
        load_manifest(HOTBOX), RunOptions(clock=clock, seed=1, knowledge="memory",
                                          scenario=SCENARIO)
    )
    platform.build()
    return platform


@pytest.mark.slow
def test_the_dashboard_follows_a_running_loop(page, tmp_path: Path) -> None:
    platform = _hotbox()
    dashboard = serve(platform, 0)
    assert dashboard.url.startswith("http://127.0.0.1:")
    # a long run, ended (thread-safely) once the browser has seen the adaptation
    runner = threading.Thread(target=platform.run, args=(120.0,), daemon=True)
    p = page.page
    try:
        p.goto(dashboard.url)
        p.wait_for_selector("body[data-rendered=true]")  # the first model arrived
        assert p.inner_text("#status") == "waiting for the loop to start"
        assert p.inner_text("#count-executed") == "0"
        runner.start()
        p.wait_for_function("document.getElementById('status').textContent === 'live: running'")
        p.wait_for_function("Number(document.body.dataset.records) > 0")
        # the loop adapts while the page watches: counts, table, timelines all follow
        p.wait_for_function(
            "Number(document.getElementById('count-executed').textContent) >= 1", timeout=60_000
        )
        assert runner.is_alive()  # seen live, not after the fact
        # and the page goes on following the run after the adaptation
        seen = int(p.evaluate("document.body.dataset.records"))
        p.wait_for_function(f"Number(document.body.dataset.records) > {seen}", timeout=30_000)
        assert p.inner_text("#status") == "live: running"
        assert "boost" in p.inner_text("#adaptations tbody tr:first-child")
        assert p.locator("#modes tr[data-block='ao'] td.mode").inner_text() == "initialized"
        assert "single process: no remote nodes" in p.inner_text("#nodes")
        for figure in ("gantt", "timing", "verdicts", "robustness", "signals"):
            assert p.evaluate(f"document.getElementById('{figure}').data.length") > 0, figure
        shot = tmp_path / "dashboard.png"
        p.screenshot(path=str(shot), full_page=True)
        print(f"dashboard screenshot: {shot}")
        assert shot.stat().st_size > 10_000
        platform.scheduler.stop()
        runner.join(30)
        assert not runner.is_alive()
    finally:
        if runner.is_alive():
            platform.scheduler.stop()
            runner.join(30)
        dashboard.close()
    # the end of the run reaches the browser: every block's mode changes to terminated
    p.wait_for_function("document.getElementById('status').textContent === 'run finished'")
    modes = p.locator("#modes td.mode").all_inner_texts()
    assert modes and set(modes) == {"terminated"}
    assert set(platform.assembly.state_manager.get_status().values()) == {"terminated"}
    assert page.errors == []


def _get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return response.status, response.headers["Content-Type"], response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read()


def test_the_server_answers_on_loopback_only_and_stops() -> None:
    platform = _hotbox("simulated")
    dashboard = serve(platform, 0)
    try:
        assert dashboard.server.server_address[0] == "127.0.0.1"
        platform.run(3.0)
        status, kind, body = _get(dashboard.url + "model.json")
        assert (status, kind) == (200, "application/json")
        model = json.loads(body)
        assert model["records"] > 0 and model["live"] is True
        assert set(model["modes"]) >= {"ao", "tc", "sm"}
        status, kind, body = _get(dashboard.url + "plotly.js")
        assert status == 200 and kind.startswith("text/javascript") and len(body) > 1_000_000
        assert _get(dashboard.url + "nothing")[0] == 404
    finally:
        dashboard.close()
    assert platform.on_record == []  # detached
    with pytest.raises(urllib.error.URLError):
        urllib.request.urlopen(dashboard.url, timeout=2)


def test_a_taken_port_is_a_clear_error() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(PlatformError, match=f"127.0.0.1:{port}.*--dashboard PORT"):
            serve(_hotbox("simulated"), port)


def test_hold_keeps_the_finished_run_until_closed() -> None:
    platform = _hotbox("simulated")
    dashboard = serve(platform, 0)
    platform.run(2.0)
    holder = threading.Thread(target=dashboard.hold, daemon=True)
    holder.start()
    status, _, body = _get(dashboard.url + "model.json")
    assert status == 200  # still served after the run
    holder.join(0.2)
    assert holder.is_alive()
    dashboard.close()  # what Ctrl-C does in the holding thread
    holder.join(10)
    assert not holder.is_alive()
    assert json.loads(body)["records"] > 0
    # every property of the run has a timeline fed by the checker's verdicts (platform.on_verdict)
    judged = {name: timeline.judged for name, timeline in dashboard.timelines.items()}
    assert judged and all(count > 0 for count in judged.values()), judged
    assert dashboard.on_verdict not in platform.on_verdict  # detached when closed
