"""The Monitor API: step, finish, warm-up, rejected records, timing of verdicts."""

from __future__ import annotations

from collections import deque

import pytest

from rasm.errors import SpecError
from rasm.properties import Verdict, compile_properties


def test_step_returns_the_verdicts_of_this_record():
    mon = compile_properties("input v: float\nproperty limit: always (v <= 0.5)\n")
    assert mon.step(0.0, {"v": 0.1}) == [Verdict("limit", 0, 0.0, True)]
    (verdict,) = mon.step(1.0, {"v": 0.9})
    assert (verdict.property, verdict.index) == ("limit", 1)
    assert (verdict.time, verdict.value) == (1.0, False)
    assert mon.step(2.0, {}) == [Verdict("limit", 2, 2.0, False)]  # sample and hold
    assert mon.finish() == []


def test_step_builds_whole_verdicts():
    # step builds each Verdict as the tuple of all its fields (without the NamedTuple's
    # __new__): a field added to Verdict must be added there too (rasm.properties.lines.Emit)
    mon = compile_properties("input a: bool\nproperty p: a -> eventually[0, 1] a\n")
    verdicts = mon.step(0, {"a": False}) + mon.step(1, {"a": True}) + mon.step(3, {"a": True})
    verdicts += mon.finish()
    assert [v.index for v in verdicts] == [0, 1, 2]
    for verdict in verdicts:
        assert type(verdict) is Verdict and len(verdict) == len(Verdict._fields)
        assert verdict == Verdict(verdict.property, verdict.index, verdict.time, verdict.value)
        assert verdict.error is None


def test_warm_up_and_defaults():
    mon = compile_properties(
        "input v: float\ninput mode: str = \"idle\"\n"
        "property p: v < 1 or mode == \"stop\"\nproperty q: mode == \"idle\"\n"
    )
    # q reads only mode, which has a default: judged from the first record
    assert [v.property for v in mon.step(0, {})] == ["q"]
    assert [v.property for v in mon.step(1, {"v": 2})] == ["p", "q"]
    assert mon.starts == [1, 0]


def test_events_are_true_only_where_set():
    mon = compile_properties("event bump\nproperty calm: not bump\n")
    values = [mon.step(t, rec)[0].value for t, rec in enumerate([{}, {"bump": True}, {}])]
    assert values == [True, False, True]


def test_future_verdicts_come_no_later_than_the_window_end_and_finish_is_inconclusive():
    mon = compile_properties("event a\nevent b\nproperty p: a -> eventually[0, 2] b\n")
    assert mon.step(0, {"a": True}) == []
    # no trigger: decided at once
    assert mon.step(1, {}) == [Verdict("p", 1, 1, True)]
    assert mon.step(2, {}) == [Verdict("p", 2, 2, True)]
    # time 2.5 > 0 + 2: record 0's window has passed
    assert mon.step(2.5, {"a": True}) == [Verdict("p", 0, 0, False)]
    out = mon.step(3, {"a": True, "b": True})
    assert sorted(out) == [Verdict("p", 3, 2.5, True), Verdict("p", 4, 3, True)]
    assert mon.step(4, {"a": True}) == []
    assert mon.finish() == [Verdict("p", 5, 4, None)]
    assert mon.finish() == []


def test_nested_future_verdicts_come_by_the_sum_of_the_bounds():
    mon = compile_properties("event a\nproperty p: eventually[0, 1] always[0, 1] a\n")
    decided_at = {}
    for t in range(8):
        for v in mon.step(t, {"a": t >= 3}):
            decided_at[v.index] = t
    assert all(decided_at[i] <= i + 3 for i in decided_at)  # first record beyond t + 2
    assert set(decided_at) == set(range(6))


def test_bad_records_are_counted_and_change_nothing():
    mon = compile_properties("input v: float\nevent e\nproperty p: v < 1 and not e\n")
    assert mon.step(1, {"v": 0.5})[0].value is True
    assert mon.step(2, {"v": "fast"}) == []
    assert mon.step(0.5, {"v": 3}) == []  # back in time
    assert mon.step(2, {"e": 1}) == []  # an event is true or false
    assert mon.step(float("nan"), {}) == []
    assert mon.step(3, {"v": 0.7})[0] == Verdict("p", 1, 3, True)
    reasons = [r.reason for r in mon.rejected]
    assert len(reasons) == 4
    assert "'v' must be a number" in reasons[0]
    assert "goes back in time" in reasons[1]
    assert "'e' must be true or false" in reasons[2]


def test_run_raises_on_bad_record_and_finished_monitor_refuses_more():
    mon = compile_properties("input v: float\nproperty p: v < 1\n")
    with pytest.raises(SpecError, match="record 1: 'v' must be a number"):
        mon.run([(0, {"v": 1}), (1, {"v": None})])
    mon = compile_properties("input v: float\nproperty p: v < 1\n")
    mon.finish()
    with pytest.raises(SpecError, match="finished"):
        mon.step(0, {"v": 1})


def test_prev_and_time_and_aggregates():
    mon = compile_properties(
        "input v: float\n"
        "property rising: prev(v) < v\n"
        "property late: time >= 2\n"
        "property busy: count[0, 1](v > 0) >= 2\n"
        "property mean: avg[0, 10](v) <= 1\n"
        "property low: min[0, 1](v) >= 0 and max(v) < 3\n"
    )
    rows = [mon.step(t, {"v": v}) for t, v in [(0, 1), (1, 2), (2, 0), (3, 5)]]
    table = {(v.property, v.index): v.value for row in rows for v in row}
    assert [table[("rising", i)] for i in range(4)] == [False, True, False, True]
    assert [table[("late", i)] for i in range(4)] == [False, False, True, True]
    assert [table[("busy", i)] for i in range(4)] == [False, True, False, False]
    assert [table[("mean", i)] for i in range(4)] == [True, False, True, False]
    assert [table[("low", i)] for i in range(4)] == [True, True, True, False]


def test_time_units():
    mon = compile_properties(
        "event a\nproperty p: once[0, 1500ms] a\nproperty q: once[0, 0.01min] a\n"
    )
    out = [mon.step(t, {"a": t == 0}) for t in (0, 1.0, 1.2, 1.6)]
    assert [row[0].value for row in out] == [True, True, True, False]
    assert [row[1].value for row in out] == [True, False, False, False]


@pytest.mark.parametrize("bound", [10, 100, 1000])
def test_memory_is_bounded_by_the_window(bound):
    # a pending queue never holds more records than the window can reach
    mon = compile_properties(f"event a\nevent b\nproperty p: a -> eventually[0, {bound}] b\n")
    (pending,) = [v for k, v in mon.program.constants.items() if k.startswith("w")]
    for t in range(3 * bound):
        mon.step(t, {"a": True})
        assert len(pending) <= bound + 1
    mon = compile_properties(f"event a\nproperty p: historically (once[{bound}, {2 * bound}] a)\n")
    (waiting,) = [v for k, v in mon.program.constants.items() if k.startswith("q")]
    for t in range(3 * bound):
        mon.step(t, {"a": True})
        assert len(waiting) <= bound + 1


def test_numeric_subclasses_are_accepted_and_non_records_refused():
    from fractions import Fraction

    class Stamp(float):
        pass

    class Count(int):
        pass

    mon = compile_properties("input x: float\ninput n: int\nproperty p: x < 1 and n >= 0\n")
    assert mon.step(Stamp(0), {"x": Fraction(1, 2), "n": Count(2)}) == [Verdict("p", 0, 0.0, True)]
    assert mon.step(1, [("x", 1)]) == []
    assert mon.step("2", {}) == []
    assert mon.step(2, {"n": True}) == []
    assert [r.reason for r in mon.rejected] == [
        "a record must map signal names to values, not list",
        "'time' must be a number, not '2'",
        "'n' must be an integer, not true",
    ]
    assert mon.step(3, {"x": 2})[0] == Verdict("p", 1, 3, False)


@pytest.mark.parametrize("order", [("a", "b"), ("b", "a")])
def test_a_prev_shared_within_a_property_is_not_shared_across_properties(order):
    # one prev(p) serves a property however often it occurs; another property, warming up
    # later, has its own: at its first record prev(p) is still undefined (false)
    formulas = {"a": "prev(p) and (prev(p) or p)", "b": "(x > 0) and prev(p)"}
    text = "event p\ninput x: float\n" + "".join(f"property {n}: {formulas[n]}\n" for n in order)
    mon = compile_properties(text)
    records = [(0, {"p": True}), (1, {"x": 1.0, "p": True}), (2, {"x": 1.0})]
    got = {(v.property, v.index): v.value for t, rec in records for v in mon.step(t, rec)}
    assert got == {("a", 0): False, ("a", 1): True, ("a", 2): True, ("b", 1): False, ("b", 2): True}


def held(monitor) -> int:
    """How many items the monitor's windows and streams hold: the lengths of the lists,
    deques, dicts and sets among its constants and their objects' attributes, all the way
    down."""
    seen: set[int] = set()

    def walk(thing) -> int:
        if id(thing) in seen or isinstance(thing, type) or callable(thing):
            return 0
        seen.add(id(thing))
        if isinstance(thing, (list, deque, dict, set)):
            return len(thing)
        if hasattr(thing, "__dict__"):
            return sum(walk(part) for part in vars(thing).values())
        return 0

    return sum(walk(value) for value in monitor.program.constants.values())


LATE = [
    "eventually[0, B] (p and always[0, 1] q)",
    "(always[0, 2] q) and (eventually[0, B] p)",
    "once[0, B] (eventually[0, 1] p)",
    "historically (eventually[0, 1] q)",
    "(eventually[0, 1] p) until[0, B] (q)",
    "(eventually[0, 1] q) until[2, B] (p)",
    "(eventually[0, 1] q) since[0, B] (p)",
    "(eventually[0, 1] q) since[2, inf] (p)",
    "count[0, B](eventually[0, 1] p) >= 1",
    "prev(eventually[0, B] p)",
]


@pytest.mark.parametrize("formula", LATE)
@pytest.mark.parametrize("bound", [10, 40])
def test_operators_over_late_values_hold_what_their_windows_reach_not_the_trace(
    formula, bound
):
    """Memory follows the bounds, not the trace: over 100 windows' worth of records (two a
    second), a monitor never holds more than a few windows' worth (plus what each window
    structure keeps until it next forgets in a batch)."""
    monitor = compile_properties(
        "event p\nevent q\nproperty late: " + formula.replace("B", str(bound)) + "\n"
    )
    most = 0
    for k in range(200 * bound):
        monitor.step(k / 2, {"p": k % 7 == 0, "q": k % 5 != 0})
        if k % 25 == 0:
            most = max(most, held(monitor))
    assert most <= 12 * bound + 2500, (formula, most)
