"""The quiet path of ``tally_into``: a record carrying none of a file's events.

The generated ``tally_into`` takes a specialised copy of its code for such a record (the events
folded in as false, see rasm.spec.fold). It must decide exactly what the general code decides:
the same verdicts, the same ``latest``/``unusual`` effects, the same rejections, the same state
afterwards. ``tally`` has no quiet path: it is the straightforward version compared with here.
"""

from __future__ import annotations

import math
import sys
from collections import OrderedDict, deque
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.spec import compile
from rasm.spec.loader import load_specification

from .reference import reference_verdicts
from .strategies import HEADER, formulas

ROOT = Path(__file__).resolve().parents[2]

# values of the wrong type, per signal of HEADER (events p, q; inputs r: bool, x: float, y: int)
WRONG = {"p": [3, "yes", None], "q": [1.5], "r": [2, "no"], "x": ["text", None], "y": [1.5, True]}
GOOD = {
    "p": st.booleans(),
    "q": st.booleans(),
    "r": st.booleans(),
    "x": st.sampled_from([-1.0, 0, 0.5, 1.5, 2.25, 10**400]),  # 10**400: float() overflows
    "y": st.sampled_from([0, 1, 2]),
}


@st.composite
def records(draw, good: dict = GOOD, wrong: dict = WRONG, events=("p", "q"), max_size=30):
    """Timed records, most of them quiet (no event key), with bad ones mixed in."""
    out = []
    t = draw(st.sampled_from([0, 0.5, 3]))
    for _ in range(draw(st.integers(1, max_size))):
        kind = draw(st.integers(0, 9))
        rec: object = {}
        names = [n for n in good if n not in events or kind >= 6]  # kinds 0-5: quiet
        for name in names:
            if draw(st.integers(0, 2)) > 0:
                rec[name] = draw(good[name])
        if kind == 7 and draw(st.booleans()):  # an event present but false: not quiet
            rec[draw(st.sampled_from(events))] = False
        time: object = t
        if kind == 8:  # a bad record: a wrong value, a wrong time, not a dict
            bad = draw(st.integers(0, 6))
            if bad == 0 and wrong:
                name = draw(st.sampled_from(sorted(wrong)))
                rec[name] = draw(st.sampled_from(wrong[name]))
            elif bad == 1:
                time = t - draw(st.sampled_from([0.5, 3]))
            elif bad == 2:
                time = draw(st.sampled_from([math.nan, "soon", None]))
            elif bad == 3:
                rec = draw(st.sampled_from([[], ["p"], "p", None, 7]))
            elif bad == 4:
                rec = OrderedDict(rec)  # a mapping, not a dict: the general path
            elif bad == 5:
                time = int(t) if t == int(t) else t  # an int time: fine
            else:
                rec["unknown"] = 1.0  # a signal no property reads
        out.append((time, rec))
        t = t + draw(st.sampled_from([0, 0.5, 1, 1, 1.5, 6]))
    return out


def state(function) -> dict:
    """What a generated function keeps between records: its closure cells and the queues of
    its namespace (copied, so that later records cannot change the snapshot)."""
    cells = {
        name: cell.cell_contents
        for name, cell in zip(function.__code__.co_freevars, function.__closure__, strict=True)
        if name != "dict_after_first"  # tally_into's own: which path the next record takes
    }
    queues = {
        name: list(value)
        for name, value in function.__globals__.items()
        if isinstance(value, deque)
    }
    return {**cells, **queues}


def outcome(function, *args) -> tuple[str, object]:
    """What a call did: ("returned", value) or ("raised", the exception's type). A value of
    10**400 overflows a float half way through a record; a monitor is not the same after that,
    but both sides must fail alike."""
    try:
        return "returned", function(*args)
    except Exception as exc:
        return "raised", type(exc)


def assert_same_as_tally(text: str, trace) -> tuple[list, list]:
    """Feed ``trace`` to ``tally_into`` of one monitor and to ``tally`` of another; everything
    observable must agree after every record. Returns (unusual pairs, finish verdicts)."""
    into, plain = compile(text), compile(text)
    latest: dict = {}
    unusual: list = []
    expected_latest: dict = {}
    expected_unusual: list = []
    for time, rec in trace:
        done, pairs = outcome(plain.tally, time, rec)
        note = lambda *pair: unusual.append(pair)  # noqa: E731
        expected = ("returned", None) if done == "returned" else (done, pairs)
        assert outcome(into.tally_into, time, rec, latest, note) == expected
        for name, value in pairs if done == "returned" else ():
            expected_latest[name] = value
            if value is not True:
                expected_unusual.append((name, value))
        assert latest == expected_latest and list(latest) == list(expected_latest)
        assert unusual == expected_unusual
        assert state(into.tally_into) == state(plain.tally)
        assert into.starts == plain.starts
        assert [vars(r) for r in into.rejected] == [vars(r) for r in plain.rejected]
    finished = outcome(into.finish)
    assert finished == outcome(plain.finish)
    return unusual, finished[1] if finished[0] == "returned" else []


def _spec(formulas_: list[str]) -> str:
    return HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))


@settings(max_examples=300, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), records())
def test_quiet_records_are_decided_as_the_general_code_decides_them(formulas_, trace):
    assert_same_as_tally(_spec(formulas_), trace)


# more events than the quiet test looks up one by one: it looks at the record's keys instead
MANY = ("p", "q", "e1", "e2", "e3", "e4")
MANY_EVENTS = "event e1\nevent e2\nevent e3\nevent e4\n"
MANY_EVENTS += "property some: once[0, 2] (e1 or e2 or e3) or (p and q)\n"
MANY_GOOD = {**GOOD, **{name: st.booleans() for name in MANY[2:]}}


@settings(max_examples=150, deadline=None)
@given(
    st.lists(formulas(3), min_size=1, max_size=2),
    st.sampled_from(["p", "q", "p and q"]),
    records(MANY_GOOD, {**WRONG, "e4": [2]}, MANY),
)
def test_quiet_records_with_many_events(formulas_, more, trace):
    text = _spec([*formulas_, f"e4 -> eventually[0, 1] ({more})"]) + MANY_EVENTS
    assert "isdisjoint" in compile(text).program.source
    assert_same_as_tally(text, trace)


@settings(max_examples=150, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), records(wrong={}))
def test_quiet_records_give_the_reference_verdicts(formulas_, trace):
    """On traces without refused records, the values handed to ``unusual`` plus those
    ``finish`` gives are the reference semantics' false and inconclusive verdicts."""
    trace = [
        (t, rec) for t, rec in trace if type(rec) is dict and isinstance(t, (int, float)) and t == t
    ]
    trace = [(t, rec) for k, (t, rec) in enumerate(trace) if all(t >= s for s, _ in trace[:k])]
    trace = [(t, rec) for t, rec in trace if rec.get("x") != 10**400]
    text = _spec(formulas_)
    unusual, finished = assert_same_as_tally(text, trace)
    expected = reference_verdicts(load_specification(text), trace)
    got = sorted((name, str(value)) for name, value in unusual)
    got += [(v.property, str(v.value)) for v in finished if v.value is not True]
    assert sorted(got) == sorted(
        (name, str(value))
        for name, values in expected.items()
        for value in values.values()
        if value is not True
    )


# The Hotbox's own property files, on records shaped like the Hotbox's (sensor, stage, monitor
# and adaptation records)
STAGES = ["monitor", "analyse", "plan", "legitimate", "execute", "elsewhere"]
HOTBOX = {
    "temperature": st.sampled_from([30.0, 36.5, 38.0, 41.5]),
    "heater_power": st.sampled_from([0.0, 55.0, 100.0, 120.0]),
    "lid_open": st.booleans(),
    "stage": st.sampled_from(STAGES),
    "duration": st.sampled_from([0.0, 0.2, 1.5]),
    "temperature_mean": st.floats(30, 40),
    **{
        event: st.booleans()
        for event in ["anomaly", "planned", "legitimate", "rejected", "trusted", "executed"]
    },
}
HOTBOX_EVENTS = ("anomaly", "planned", "legitimate", "rejected", "trusted", "executed")
HOTBOX_WRONG = {"temperature": ["hot"], "stage": [3], "duration": ["long"], "executed": [2]}
FILES = [
    "properties/maple_k.rv",
    "properties/adaptation.rv",
    "examples/hotbox/properties/hotbox.rv",
]


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(FILES), records(HOTBOX, HOTBOX_WRONG, HOTBOX_EVENTS, max_size=60))
def test_the_hotbox_property_files_on_hotbox_like_records(path, trace):
    assert_same_as_tally((ROOT / path).read_text(), trace)


def test_the_quiet_path_is_taken_for_a_record_without_events():
    # the equivalence tests above would pass vacuously if the quiet path never ran
    monitor = compile(HEADER + "property a: always (p -> x > 0)\n")
    code = monitor.tally_into.__code__
    source = monitor.program.source.splitlines()
    quiet = next(n for n, line in enumerate(source, 1) if "rec.__class__ is dict" in line)
    indent = source[quiet - 1].index("if")
    # the general code: the first line after the quiet branch, at the branch's indentation
    general = next(
        n for n, line in enumerate(source, 1) if n > quiet and line.index(line.strip()) == indent
    )
    lines: list[int] = []

    def trace(frame, event, arg):
        if frame.f_code is code and event == "line":
            lines.append(frame.f_lineno)
        return trace

    latest: dict = {}
    sys.settrace(trace)
    try:
        monitor.tally_into(0.0, {"x": 1.0}, latest, print)
        first, lines[:] = list(lines), []
        monitor.tally_into(1.0, {"x": 1.0}, latest, print)
        quiet_lines, lines[:] = list(lines), []
        monitor.tally_into(2.0, {"x": 1.0, "p": True}, latest, print)
    finally:
        sys.settrace(None)
    assert all(n == quiet or n >= general for n in first)  # the first record: general code
    assert all(quiet <= n < general for n in quiet_lines)  # never in the general code
    assert all(n == quiet or n >= general for n in lines)  # straight to the general code
    assert latest == {"a": True} and monitor.starts == [0]


def test_a_quiet_record_that_fails_half_way_hands_nothing_over():
    text = "event e\ninput n: int\nproperty small: always (n < 10)\n"
    text += "property ratio: always (1.5 * n > 0 or e)\n"
    monitor = compile(text)
    latest: dict = {}
    unusual: list = []
    monitor.tally_into(0.0, {"n": 20}, latest, lambda *pair: unusual.append(pair))
    with pytest.raises(OverflowError):
        monitor.tally_into(1.0, {"n": 10**400}, latest, lambda *pair: unusual.append(pair))
    assert latest == {"small": False, "ratio": True} and unusual == [("small", False)]


@st.composite
def with_refusals(draw):
    """Records with refused ones among them: good values for every signal but one, which is
    wrong (or the time goes back), so that a partial update would show."""
    trace = draw(records(max_size=20))
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(trace)))
        rec = {name: draw(value) for name, value in GOOD.items() if name not in ("p", "q")}
        if draw(st.booleans()):
            rec.update((name, draw(GOOD[name])) for name in ("p", "q"))
        time = trace[at - 1][0] if at else 0
        if draw(st.integers(0, 3)) == 0 and isinstance(time, (int, float)):
            time = time - 1
        else:
            wrong = draw(st.sampled_from(sorted(WRONG)))
            rec[wrong] = draw(st.sampled_from(WRONG[wrong]))
        trace.insert(at, (time, rec))
    return trace


@settings(max_examples=200, deadline=None)
@given(st.lists(formulas(3), min_size=1, max_size=3), with_refusals())
def test_a_refused_record_changes_nothing(formulas_, trace):
    """Whatever a refused record holds (good values next to the bad one, on either path), the
    monitor goes on as if it had never come."""
    text = _spec(formulas_)
    full, without = compile(text), compile(text)
    seen: list = []
    kept: list = []
    for time, rec in trace:
        refused = len(full.rejected)
        got = outcome(full.tally_into, time, rec, {}, lambda *pair: seen.append(pair))
        if len(full.rejected) == refused:
            note = lambda *pair: kept.append(pair)  # noqa: E731
            assert outcome(without.tally_into, time, rec, {}, note) == got
        assert seen == kept
    assert outcome(full.finish) == outcome(without.finish)
