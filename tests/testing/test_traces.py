"""traces(): every declaration respected; false properties falsified and shrunk to short traces."""

from __future__ import annotations

import json

import pytest
from hypothesis import Phase, find, given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties
from rasm.testing import signal_domains, traces
from rasm.trace import parse_trace

PROPS = """
input velocity: float          # m/s, range [0, 1.5]
input stops: int = 0           # range [0, 10]
input mode: str = "idle"
input docked: bool
input load: float
event anomaly, executed

property slow_when_docking:
    always (mode == "dock" -> velocity <= 0.1)
property timely:
    always (anomaly -> eventually[0, 2s] executed)
property bounded_load:
    always (load < 250 or mode == "emergency")
"""

FAST = settings(
    max_examples=60,
    deadline=None,
    database=None,
    phases=[Phase.explicit, Phase.reuse, Phase.generate, Phase.shrink],
)
SEARCH = settings(FAST, max_examples=500)  # enough to meet a falsifying trace every time


def check_declarations(trace, *, ranges, max_gap, min_records=1, max_records=50):
    assert min_records <= len(trace) <= max_records
    times = [r["time"] for r in trace]
    assert times[0] == 0.0
    assert all(0 <= b - a <= max_gap + 1e-9 for a, b in zip(times, times[1:], strict=False))
    allowed = {"time", "velocity", "stops", "mode", "docked", "load", "anomaly", "executed"}
    for record in trace:
        assert set(record) <= allowed
        for event in ("anomaly", "executed"):
            assert record.get(event, True) is True  # events appear only when they happen
        if "velocity" in record:
            low, high = ranges["velocity"]
            assert isinstance(record["velocity"], float) and low <= record["velocity"] <= high
        if "stops" in record:
            low, high = ranges["stops"]
            assert type(record["stops"]) is int and low <= record["stops"] <= high
        if "mode" in record:
            assert record["mode"] in ("dock", "emergency", "idle", "other")
        if "docked" in record:
            assert type(record["docked"]) is bool
        if "load" in record:
            assert isinstance(record["load"], float) and abs(record["load"]) <= 500
    # inputs without a default are all set by the first record: properties start at once
    assert {"velocity", "docked", "load"} <= set(trace[0])


@FAST
@given(st.data())
def test_comment_ranges_types_events_and_times_are_respected(data):
    trace = data.draw(traces(PROPS))
    # max_gap defaults to 1.5 times the largest bound (2 s)
    check_declarations(trace, ranges={"velocity": (0, 1.5), "stops": (0, 10)}, max_gap=3.0)
    # every record is one `rasm check` accepts, and the monitor refuses none
    parse_trace([json.dumps(r) for r in trace], compile_properties(PROPS).spec.signals)
    monitor = compile_properties(PROPS)
    for record in trace:
        values = dict(record)
        monitor.step(values.pop("time"), values)
    assert monitor.rejected == []


@FAST
@given(
    st.data(),
    st.tuples(st.floats(-5, 5), st.floats(0, 5)),
    st.tuples(st.integers(-3, 3), st.integers(0, 4)),
    st.floats(0, 4),
    st.integers(1, 5),
    st.integers(0, 6),
)
def test_given_ranges_and_sizes_are_respected(data, velocity, stops, max_gap, low, extra):
    ranges = {
        "velocity": (velocity[0], velocity[0] + velocity[1]),
        "stops": (stops[0], stops[0] + stops[1]),
    }
    trace = data.draw(
        traces(PROPS, ranges=ranges, max_gap=max_gap, min_records=low, max_records=low + extra)
    )
    check_declarations(
        trace, ranges=ranges, max_gap=max_gap, min_records=low, max_records=low + extra
    )


@FAST
@given(traces(PROPS, ranges={"mode": ["dock", "navigate"]}))
def test_a_list_of_values_is_a_range_for_strings(trace):
    assert {r["mode"] for r in trace if "mode" in r} <= {"dock", "navigate"}


def test_traces_accept_a_path(tmp_path):
    path = tmp_path / "props.rv"
    path.write_text(PROPS)
    domains = signal_domains(str(path))
    assert (domains["velocity"].low, domains["velocity"].high) == (0.0, 1.5)
    assert domains["mode"].choices == ("dock", "emergency", "idle", "other")
    # no range given: twice the largest constant the signal is compared with
    assert (domains["load"].low, domains["load"].high) == (-500.0, 500.0)
    assert domains["stops"].required is False and domains["velocity"].required is True
    first = find(traces(path, max_records=3), lambda t: len(t) >= 1, settings=FAST)
    assert first == [{"time": 0.0, "velocity": 0.0, "docked": False, "load": 0.0}]


def holds(text, trace):
    monitor = compile_properties(text)
    verdicts = []
    for record in trace:
        values = dict(record)
        verdicts += monitor.step(values.pop("time"), values)
    verdicts += monitor.finish()
    return all(v.value is not False for v in verdicts)


def test_a_false_limit_is_falsified_by_one_record():
    text = "input velocity: float  # range [0, 2]\nproperty limit: always (velocity <= 1.5)\n"
    minimal = find(traces(text, max_records=10), lambda t: not holds(text, t), settings=SEARCH)
    assert len(minimal) == 1
    assert set(minimal[0]) == {"time", "velocity"} and minimal[0]["velocity"] > 1.5


def test_a_false_deadline_is_shrunk_to_an_event_and_empty_records_past_the_window():
    text = (
        "event anomaly\nevent executed\n"
        "property timely: always (anomaly -> eventually[0, 2s] executed)\n"
    )
    minimal = find(traces(text, max_records=10), lambda t: not holds(text, t), settings=SEARCH)
    # hypothesis may keep bare intermediate records (it cannot delete one and lengthen the next
    # gap in one move); everything else is gone: one anomaly, then bare times until just past
    # the window
    assert minimal[0] == {"time": 0.0, "anomaly": True}
    assert all(set(r) == {"time"} for r in minimal[1:])
    assert minimal[-1]["time"] > 2.0 and minimal[-2]["time"] <= 2.0


def test_undeclared_signals_get_their_inferred_types():
    domains = signal_domains('property p: always (x > 1 and ok and m != "a")')
    assert {n: d.type for n, d in domains.items()} == {"x": "float", "ok": "bool", "m": "str"}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"ranges": {"velocty": (0, 1)}}, r"'velocty', which is not an input .* velocity"),
        ({"ranges": {"velocity": (2, 1)}}, r"low <= high"),
        ({"ranges": {"mode": (0, 1)}}, r"give a list of its values"),
        ({"ranges": {"stops": [1.5]}}, r"not a int"),
        ({"min_records": 5, "max_records": 2}, r"min_records <= max_records"),
        ({"max_gap": -1}, r"max_gap must be"),
    ],
)
def test_bad_arguments_say_what_to_change(kwargs, message):
    with pytest.raises(ValueError, match=message):
        traces(PROPS, **kwargs)


def test_a_missing_file_is_reported():
    with pytest.raises(FileNotFoundError, match="pass the path of a .rv file"):
        traces("no/such/file.rv")
