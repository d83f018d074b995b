"""``rasm report`` in a real browser: a Hotbox trace's page loads cleanly, every view has data,
and the adaptation table's links move the timelines."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rasm.cli import main

HOTBOX_PROPS = Path(__file__).resolve().parents[2] / "examples" / "hotbox" / "properties"

# the number of traces plotly drew in a figure
TRACES = "id => (document.getElementById(id).data || []).length"


@pytest.fixture
def hotbox_report(hotbox_trace: Path, tmp_path: Path) -> Path:
    out = tmp_path / "report.html"
    code = main(["report", str(hotbox_trace), "-o", str(out)])
    assert code == 0
    return out


def _open(page, path: Path) -> None:
    page.page.goto(path.as_uri())
    page.page.wait_for_selector("body[data-rendered=true]")


def test_report_is_self_contained(hotbox_report: Path) -> None:
    html = hotbox_report.read_text(encoding="utf-8")
    assert "<script src=" not in html and "<link rel=\"stylesheet\"" not in html
    assert "http://" not in html.split("<script>", 1)[0]  # nothing fetched by the head
    assert 'id="rasm-data"' in html


@pytest.mark.slow
def test_every_view_renders_with_data(page, hotbox_report: Path, tmp_path: Path) -> None:
    p = page.page
    fetched: list[str] = []  # the page must need no network: any request is refused and noted
    p.route("http*://**", lambda route: (fetched.append(route.request.url), route.abort()))
    _open(page, hotbox_report)
    for figure in ("gantt", "gantt-detail", "timing", "verdicts", "robustness", "signals"):
        assert p.evaluate(TRACES, figure) > 0, figure
        assert p.locator(f"#{figure} .main-svg").count() > 0, figure  # plotly drew SVG
    assert p.evaluate(TRACES, "gantt") == 5  # one bar trace per MAPLE-K stage
    assert p.locator("#timing-table tbody tr").count() == 5
    assert p.locator("#verdict-table tbody tr").count() >= 8  # the platform's properties
    assert p.locator(".missing:visible").count() == 0
    assert p.locator("#notes").is_hidden()
    rows = p.locator("#adaptations tbody tr")
    assert rows.count() == 3
    assert "executed" in rows.nth(0).inner_text()
    assert "boost" in rows.nth(0).inner_text()
    assert p.inner_text("#count-executed") == "3"
    shot = tmp_path / "report.png"
    p.screenshot(path=str(shot), full_page=True)
    print(f"report screenshot: {shot}")
    assert shot.stat().st_size > 10_000
    assert page.errors == []
    assert fetched == []


@pytest.mark.slow
def test_app_properties_are_drawn_with_props(page, hotbox_trace: Path, tmp_path: Path) -> None:
    # the parser may not offer --props yet: the API is what it calls
    from rasm.report import write_report

    out = tmp_path / "with-props.html"
    write_report(hotbox_trace, out, [HOTBOX_PROPS / "hotbox.rv"])
    _open(page, out)
    names = page.page.locator("#verdict-table tbody tr td:first-child").all_inner_texts()
    assert "temperature_band" in names and "heater_rating" in names
    assert "timely_adaptation" in names and "timely_response" in names
    signals = page.page.evaluate("document.getElementById('signals').data.map(d => d.name)")
    read = ["heater_mode", "heater_power", "lid_open", "temperature"]
    assert signals[:4] == read  # read by properties: first
    assert page.errors == []


@pytest.mark.slow
def test_adaptation_links_move_the_timelines(page, hotbox_report: Path) -> None:
    _open(page, hotbox_report)
    p = page.page
    link = p.locator("#adaptation-2 a.goto")
    t = float(link.get_attribute("data-time"))
    link.click()
    p.wait_for_selector(f"body[data-focus='{link.get_attribute('data-time')}']")
    assert p.locator("#adaptation-2.selected").count() == 1
    assert p.locator("#adaptations tr.selected").count() == 1
    for figure in ("gantt", "verdicts", "signals"):
        low, high = p.evaluate(f"document.getElementById('{figure}').layout.xaxis.range")
        assert low < t < high and high - low < 40, figure  # zoomed around the adaptation
        focus = p.evaluate(
            f"document.getElementById('{figure}').layout.shapes.filter(s => s.name === 'focus')"
        )
        assert [s["x0"] for s in focus] == [t], figure
    assert p.evaluate("location.hash") == f"#t={link.get_attribute('data-time')}"
    assert link.get_attribute("data-time") in p.inner_text("#detail-title").replace(".000", "")
    p.click("#focus-reset")
    p.wait_for_function("document.body.dataset.focus === undefined")
    assert p.evaluate("document.getElementById('signals').layout.xaxis.autorange") is True
    assert page.errors == []


@pytest.mark.slow
def test_a_link_to_a_moment_opens_there(page, hotbox_report: Path) -> None:
    page.page.goto(hotbox_report.as_uri() + "#t=39")  # the boost at the second lid opening
    page.page.wait_for_selector("body[data-focus='39']")
    assert page.page.locator("#adaptation-3.selected").count() == 1
    assert page.errors == []


@pytest.mark.slow
def test_a_trace_without_loop_records_says_what_is_missing(page, tmp_path: Path) -> None:
    trace = tmp_path / "plain.jsonl"
    trace.write_text(
        "\n".join(json.dumps({"time": i / 10, "velocity": i / 100}) for i in range(20)) + "\n"
    )
    out = tmp_path / "plain.html"
    assert main(["report", str(trace), "-o", str(out)]) == 0
    _open(page, out)
    p = page.page
    notes = p.inner_text("#notes")
    assert "no MAPLE-K stage timing" in notes and "no adaptations" in notes
    assert "No MAPLE-K stage timing" in p.inner_text("#gantt")
    assert "No stage durations" in p.inner_text("#timing")
    assert "No adaptations" in p.inner_text("#adaptations-missing")
    assert p.evaluate(TRACES, "signals") == 1  # velocity is still drawn
    assert page.errors == []


@pytest.mark.slow
def test_a_report_without_properties_says_so(page, hotbox_trace: Path, tmp_path: Path) -> None:
    from rasm.report import write_report

    out = tmp_path / "no-props.html"
    write_report(hotbox_trace, out, platform_props=False)
    _open(page, out)
    assert "No properties" in page.page.inner_text("#verdicts")
    assert "no properties checked" in page.page.inner_text("#notes")
    assert page.errors == []


@pytest.mark.slow
def test_one_slow_iteration_does_not_flatten_the_gantt(page, tmp_path: Path) -> None:
    lines = []
    for i in range(40):
        slow = 0.050 if i == 7 else 0.0001  # one 50 ms monitor among 0.1 ms ones
        lines.append({"time": i / 2, "stage": "monitor", "duration": slow})
        lines.append({"time": i / 2, "stage": "analyse", "duration": 0.00005})
    trace = tmp_path / "slow.jsonl"
    trace.write_text("\n".join(json.dumps(r) for r in lines) + "\n")
    out = tmp_path / "slow.html"
    assert main(["report", str(trace), "-o", str(out)]) == 0
    _open(page, out)
    low, high = page.page.evaluate("document.getElementById('gantt').layout.yaxis.range")
    assert low == 0 and 0.15 <= high < 1  # ms: the 0.15 ms iterations fill the plot
    assert "3.500 s took 50.050 ms" in page.page.inner_text("#gantt-note")
    assert "iteration at 3.500 s" in page.page.inner_text("#detail-title")  # the slowest
    assert page.errors == []


STATES_PROPS = """
input velocity: float
property velocity_limit:
    always (velocity <= 1.0)
property fast_enough:
    always (velocity >= 0.2)
property typo:
    always (velocty <= 1.0)
"""


@pytest.mark.slow
def test_every_state_is_shown_in_words_and_only_satisfied_is_green(page, tmp_path: Path) -> None:
    """A property that never saw its signal, one in error and one violated: none looks like
    one that holds."""
    from rasm.report.build import build_model
    from rasm.report.page import render_page
    from rasm.report.verdicts import VerdictTimeline

    trace = tmp_path / "t.jsonl"
    trace.write_text("".join(
        json.dumps({"time": t / 2, "velocity": v}) + "\n" for t, v in enumerate([0.5, 0.1, 0.5])
    ))
    props = tmp_path / "p.rv"
    props.write_text(STATES_PROPS)
    model = build_model(trace, [props], platform_props=False)
    assert "property typo not judged: no value for velocty in this trace" in model["missing"]
    # a property the checker could not evaluate at one record (as a monitor reports it)
    budget = VerdictTimeline("budget", f"{props}:9:10", ["x"])
    budget.add(0.0, True)
    budget.add(0.5, False, "the monitor raised OverflowError: the sum overflowed")
    budget.add(1.0, True)
    model["properties"]["timelines"].append(budget.to_dict())
    out = tmp_path / "states.html"
    out.write_text(render_page(model, title="states"), encoding="utf-8")
    _open(page, out)
    cells = page.page.eval_on_selector_all(
        "#verdict-table tbody tr",
        "rows => rows.map(r => [r.cells[0].innerText, r.cells[1].innerText,"
        " getComputedStyle(r.cells[1]).color, r.cells[5].innerText])",
    )
    shown = {name: (word, color, why) for name, word, color, why in cells}
    green = shown["velocity_limit"][1]
    assert shown["velocity_limit"][0] == "satisfied" and green == "rgb(26, 127, 55)"
    assert shown["fast_enough"][:1] == ("violated",)
    assert shown["typo"][0] == "not judged"
    assert shown["typo"][2] == "not judged: no value for velocty"
    assert shown["budget"][0] == "error" and "OverflowError" in shown["budget"][2]
    assert {shown[name][1] for name in ("fast_enough", "typo", "budget")}.isdisjoint({green})
    assert not page.errors


@pytest.mark.slow
def test_fallback_episodes_violation_episodes_and_where_properties_are_defined(
    page, tmp_path: Path
) -> None:
    """A 0.4 s near miss is one episode, not six violations; the fallback an episode with its
    reason, action and hand-back; and the platform's properties are at rasm:properties/…"""
    records = [{"time": round(k / 10, 1), "speed": 0.5} for k in range(40)]
    for k in (10, 11, 12, 13):  # too fast from 1.0 s to 1.3 s, then slow again at 1.4 s
        records[k]["speed"] = 1.5
    records[10]["fallback"] = "engaged"
    records[10]["explanation"] = "fallback engaged: veto property slow violated at t=1"
    records.insert(11, {"time": 1.0, "trusted": True, "plan": "f1"})
    records.insert(12, {"time": 1.0, "executed": True, "plan": "f1",
                        "explanation": "sent to drive on robot/drive"})
    records[30]["fallback"] = "released"
    records[30]["explanation"] = "control handed back: no trigger for 1.5 s"
    trace = tmp_path / "t.jsonl"
    trace.write_text("".join(json.dumps(r) + "\n" for r in records))
    props = tmp_path / "p.rv"
    props.write_text("input speed: float\nproperty slow:\n    always (speed <= 1.0)\n")
    out = tmp_path / "fallback.html"
    assert main(["report", str(trace), "-o", str(out), "--props", str(props)]) == 0
    _open(page, out)
    p = page.page
    fallback = p.locator("#fallback-table tbody tr")
    assert fallback.count() == 1
    text = fallback.inner_text()
    assert "veto property slow violated at t=1" in text
    assert "sent to drive on robot/drive" in text
    assert "control handed back: no trigger for 1.5 s" in text and "1.800 s" in text
    assert p.inner_text("#count-fallback") == "1"
    assert p.locator("#adaptations tbody tr").count() == 0  # no "(no anomaly record)" row
    episodes = [e for e in p.locator("#violations li.episode").all_inner_texts()
                if " slow violated" in e]
    # six records (the fallback's two among them) from 1.0 s until speed is slow at 1.4 s
    assert len(episodes) == 1, episodes
    assert "1.000 s slow violated for 0.400 s (6 records at records 10–15)" in episodes[0]
    assert "speed <= 1.0 failed" in episodes[0]
    cells = p.eval_on_selector_all(
        "#verdict-table tbody tr", "rows => rows.map(r => [r.cells[0].innerText, "
        "r.cells[2].innerText, r.cells[7].innerText])")
    where = {name: (violations, defined) for name, violations, defined in cells}
    assert where["slow"][0] == "6 (1 episode)"
    assert where["slow"][1] == f"{props}:2:10"  # a file given: as given
    assert where["stage_order"][1].startswith("rasm:properties/maple_k.rv:")
    assert where["no_oscillation"][1].startswith("rasm:properties/adaptation.rv:")
    assert not page.errors


def test_each_numeric_propertys_robustness_is_drawn_beside_the_verdicts(
    page, hotbox_report: Path
) -> None:
    """One line per property with a finite robustness (a gap where it is infinite), the
    boolean ones named; the robustness keys are not drawn again as knowledge signals."""
    p = page.page
    _open(page, hotbox_report)
    names = p.evaluate("document.getElementById('robustness').data.map(d => d.name)")
    assert {"temperature_band", "heater_rating", "stage_budget", "no_oscillation"} <= set(names)
    assert "stage_order" not in names and "stage_order" in p.inner_text("#robustness-note")
    band = p.evaluate("document.getElementById('robustness').data"
                      ".find(d => d.name === 'temperature_band').y")
    assert len(band) > 100 and all(0 < v < 3.5 for v in band)
    signals = p.evaluate("document.getElementById('signals').data.map(d => d.name)")
    assert not [s for s in signals if s.startswith("robustness_")]
    assert page.errors == []
