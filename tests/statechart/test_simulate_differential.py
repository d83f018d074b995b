"""`rasm simulate` takes exactly the macro steps stock sismic takes with the same timed events.

The events' times are on a binary grid (multiples of 1/4 s), where stock sismic's binary
arithmetic is exact; off it, rasm's timers hold at their deadline where stock's can miss it
(the one departure, tested in test_exact_timers.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sismic.clock import SimulatedClock
from sismic.interpreter import Interpreter as StockInterpreter
from sismic.io import import_from_yaml

from rasm.cli import main
from rasm.statechart import load_statechart
from rasm.statechart.simulate import TimedEvent, simulate

ROOT = Path(__file__).resolve().parents[2]
CHARTS = sorted(
    [
        *ROOT.joinpath("statecharts").glob("*.yaml"),
        *Path(__file__).parent.joinpath("charts").glob("*.yaml"),
    ]
)


def stock_steps(path: Path, events: list[TimedEvent]) -> list[dict]:
    """Drive stock sismic the ordinary way: run at 0, then per event set time, queue, run (a
    line without an event: set time, run)."""
    clock = SimulatedClock()
    interp = StockInterpreter(import_from_yaml(path.read_text()), clock=clock)
    out = []

    def run():
        while (step := interp.execute_once()) is not None:
            out.append(
                {
                    "time": step.time,
                    "event": step.event.name if step.event is not None else None,
                    "configuration": sorted(interp.configuration),
                    "entered": list(step.entered_states),
                    "exited": list(step.exited_states),
                }
            )

    run()
    for event in events:
        clock.time = event.time
        if event.name is not None:
            interp.queue(event.name, **event.data)
        run()
    return out


def event_names(path: Path) -> list[str | None]:
    chart = load_statechart(path)
    names = sorted({t.event for t in chart.transitions if t.event})
    return names + ["unknown_event", None]  # None: a line that only moves the clock


def timed_events(names: list[str | None]):
    gaps = st.sampled_from([0, 0, 0.25, 0.5, 1, 1.5, 2, 3, 6])
    return st.lists(st.tuples(gaps, st.sampled_from(names)), max_size=25).map(
        lambda pairs: _accumulate(pairs)
    )


def _accumulate(pairs):
    time, out = 0.0, []
    for gap, name in pairs:
        time += gap
        out.append(TimedEvent(time, name, {}))
    return out


def _check(path: Path, data) -> None:
    events = data.draw(timed_events(event_names(path)))
    ours = [s.as_dict() for s in simulate(path, events)]
    assert ours == stock_steps(path, events)


def test_every_chart_is_covered():
    names = {p.stem for p in CHARTS}
    assert {"adaptation_orchestrator", "core", "features", "delayed"} <= names


@pytest.mark.slow
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_platform_and_feature_charts_match_stock_sismic(data):
    path = data.draw(st.sampled_from(CHARTS))
    _check(path, data)


def test_cli_json_output_matches_stock_sismic(tmp_path, capsys):
    chart = Path(__file__).parent / "charts" / "features.yaml"
    events = [
        TimedEvent(0.5, "power"),
        TimedEvent(1, "work"),
        TimedEvent(1, "step"),
        TimedEvent(4, "work"),
        TimedEvent(4.5, "glitch"),
        TimedEvent(5, "power"),
        TimedEvent(6, "power"),
    ]
    events_file = tmp_path / "events.jsonl"
    events_file.write_text(
        "".join(
            json.dumps({"time": e.time, "event": e.name, "data": e.data}) + "\n" for e in events
        )
    )
    assert main(["simulate", str(chart), "--events", str(events_file), "--format", "json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines == stock_steps(chart, events)
    assert lines[0]["event"] is None and lines[0]["time"] == 0
    # the after(2) timer in `busy` fired on the event at t=4, as stock sismic does
    assert any(s["event"] is None and "idle" in s["entered"] for s in lines[1:])


def test_a_stage_chart_runs_on_its_own_with_each_events_context(tmp_path, capsys):
    # the platform sets knowledge before each stage event; an event's context does the same
    chart = tmp_path / "analyse.yaml"
    chart.write_text(
        "statechart:\n  name: analyse\n  root state:\n    name: r\n    transitions:\n"
        "      - event: analyse\n        guard: knowledge.get('t', 0) > 50\n"
        "        action: send('anomaly', reason='hot', t=knowledge['t'])\n"
        "      - event: analyse\n        guard: knowledge.get('t', 0) <= 50\n"
        "        action: send('no_anomaly')\n"
    )
    events = [TimedEvent(1.0, "analyse", context={"knowledge": {"t": 20}}),
              TimedEvent(2.0, "analyse", context={"knowledge": {"t": 70}}),
              TimedEvent(3.0, "analyse")]  # the knowledge set last stays
    answers = [step.sent for step in simulate(chart, events) if step.event == "analyse"]
    assert answers == [[("no_anomaly", {})], [("anomaly", {"reason": "hot", "t": 70})],
                       [("anomaly", {"reason": "hot", "t": 70})]]
    lines = tmp_path / "events.jsonl"
    lines.write_text('{"time": 1, "event": "analyse", "context": {"knowledge": {"t": 99}}}\n')
    assert main(["simulate", str(chart), "--events", str(lines)]) == 0
    assert "> sent:    anomaly(reason='hot', t=99)" in capsys.readouterr().out
