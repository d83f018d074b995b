"""What ``rasm run`` shows live: each property's latest verdict in words, only "holds" green."""

from __future__ import annotations

import io

from rich.console import Console

from rasm import Platform, RunOptions
from rasm.cli.console import LiveView
from tests.platform.guarded import write_guarded_app


def _lines(view: LiveView, time: float, *, styled: bool) -> dict[str, str]:
    """The live view as text: the line of each property (with colour codes when ``styled``)."""
    out = io.StringIO()
    console = Console(file=out, width=200, force_terminal=styled, color_system="standard")
    console.print(view.render(time))
    lines = {}
    for line in out.getvalue().splitlines():
        for name in ("slow", "budget", "steady"):
            if f" {name} " in f" {line} ":
                lines[name] = line
    return lines


def test_the_live_view_says_which_properties_are_not_judged_yet(tmp_path):
    app = write_guarded_app(
        tmp_path / "app", signals={"heading": "float"}, inputs="input heading: float\n",
        extra="\nproperty steady:\n    always (heading <= 90)\n", every=8,
    )
    platform = Platform(app, RunOptions(clock="simulated", seed=1))
    platform.start()
    try:
        platform.scheduler.run_until(platform.clock.time + 2.0)
        view = LiveView(platform, Console(file=io.StringIO()), duration=2.0)
        plain = _lines(view, platform.clock.time, styled=False)
        styled = _lines(view, platform.clock.time, styled=True)
    finally:
        platform.stop()
    assert "not judged yet" in plain["steady"] and "holds" in plain["slow"]
    green = "\x1b[32m"
    assert green in styled["slow"].split("slow", 1)[1]
    assert green not in styled["steady"].split("steady", 1)[1]
