"""docs/statecharts.md stays true: every event of every chart is documented, and the tutorial's
chart, events file and output are what `rasm lint` and `rasm simulate` really say."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rasm.lint import lint_file
from rasm.statechart.simulate import format_steps, read_events, simulate

from .support import BLOCKS, LIFECYCLE, MODES, REPO, chart_path, load

DOC = (REPO / "docs" / "statecharts.md").read_text(encoding="utf-8")
SEND = re.compile(r"send\('(\w+)'")


def section(heading: str) -> str:
    """The text under a `### heading` up to the next heading of level 2 or 3."""
    match = re.search(rf"^### {re.escape(heading)}\n(.*?)(?=^##)", DOC, re.S | re.M)
    assert match, f"docs/statecharts.md has no section '### {heading}'"
    return match.group(1)


def table_events(text: str) -> set[str]:
    """Event names in the first column of the section's tables (`(timeout)` rows excluded)."""
    return set(re.findall(r"^\| `(\w+)` \|", text, re.M))


def sent_events(chart) -> set[str]:
    code = [t.action or "" for t in chart.transitions]
    for name in chart.states:
        state = chart.state_for(name)
        code += [getattr(state, "on_entry", None) or "", getattr(state, "on_exit", None) or ""]
    return {name for text in code for name in SEND.findall(text)}


def test_the_lifecycle_table_lists_exactly_the_lifecycle_events():
    assert table_events(section("Lifecycle events (every chart)")) == {e for _, e in LIFECYCLE}


@pytest.mark.parametrize("name", BLOCKS)
def test_every_event_of_the_chart_is_in_its_table_and_nothing_else(name):
    chart = load(chart_path(name))
    documented = table_events(section(f"`{name}`"))
    lifecycle = {e for _, e in LIFECYCLE}
    reacts_to = {t.event for t in chart.transitions if t.event is not None}
    sends = sent_events(chart)
    assert reacts_to - lifecycle <= documented, "undocumented events"
    assert documented <= reacts_to | sends, "documented events the chart does not have"
    assert sends <= documented, "sent events missing from the table"


@pytest.mark.parametrize("name", BLOCKS)
def test_every_timer_of_the_chart_has_a_timeout_row(name):
    chart = load(chart_path(name))
    timers = [t for t in chart.transitions if t.event is None and "after(" in (t.guard or "")]
    rows = re.findall(r"^\| \(timeout\) \| ([^|]+) \|", section(f"`{name}`"), re.M)
    sources = {s.strip() for row in rows for s in row.split(",")}
    assert {t.source for t in timers} == sources


def tutorial_block(label: str) -> str:
    match = re.search(rf"<!-- tutorial: {re.escape(label)} -->\n```\w+\n(.*?)```", DOC, re.S)
    assert match, f"no tutorial block '{label}'"
    return match.group(1)


@pytest.fixture
def tutorial(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("lidar_probe.yaml").write_text(tutorial_block("lidar_probe.yaml"), encoding="utf-8")
    Path("scans.jsonl").write_text(tutorial_block("scans.jsonl"), encoding="utf-8")
    return tmp_path


def test_the_tutorial_chart_passes_rasm_lint_and_follows_the_convention(tutorial):
    assert lint_file(Path("lidar_probe.yaml")) == []
    from rasm.statechart import load_statechart

    chart = load_statechart("lidar_probe.yaml")
    assert chart.name == "lidar_probe" and chart.root == "lifecycle"
    assert sorted(chart.children_for("lifecycle")) == sorted(MODES)
    leaving = {
        (t.source, t.event, t.target)
        for t in chart.transitions
        if t.source in MODES and t.target not in chart.descendants_for(t.source)
    }
    assert leaving == {(m, e, target) for (m, e), target in LIFECYCLE.items()}


def test_the_tutorial_output_is_what_rasm_simulate_prints(tutorial):
    steps = simulate("lidar_probe.yaml", read_events("scans.jsonl"))
    assert format_steps(steps, "json") == tutorial_block("output")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "        initial: waiting\n",
            "        initial: waitng\n",
            "lidar_probe.yaml:40:18: initial state 'waitng' of 'initialized' is not one of its"
            " children",
        ),
        (
            "guard: after(scan_timeout)\n",
            "guard: after(scan_timeout\n",
            "lidar_probe.yaml:54:29: invalid Python expression in 'guard': '(' was never closed",
        ),
    ],
)
def test_the_tutorial_lint_messages_are_what_rasm_lint_prints(tutorial, old, new, message):
    text = Path("lidar_probe.yaml").read_text(encoding="utf-8")
    assert text.count(old) == 1
    Path("lidar_probe.yaml").write_text(text.replace(old, new), encoding="utf-8")
    assert message in DOC
    assert lint_file(Path("lidar_probe.yaml")) == [message]
