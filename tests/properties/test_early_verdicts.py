"""Verdicts come as soon as they are decided: online (``Monitor.step``) and offline
(``Monitor.take``), against the reference evaluator.

**Decided.** A verdict for record i is *decided at record k* (k >= i) when the records r0 … rk
already fix it: SPEC §5's three-valued value of the formula at i over the trace r0 … rk — where
a value that depends on records after rk is inconclusive, and Kleene's logic combines the
rest — is true or false. The reference evaluator computes exactly that on the prefix, so
``decided_at`` runs it on every prefix and notes the first k where the value at i is two-valued.

Such a value is forced: every continuation of the trace gives the same verdict
(``test_a_decided_verdict_is_the_same_for_every_continuation``, over continuations that close
every window). And where each signal occurs once in the formula, a verdict not decided yet is
really open: two continuations give different verdicts
(``test_a_verdict_not_decided_yet_still_depends_on_the_continuation``).
"""

from __future__ import annotations

import contextlib
from collections import deque

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import Verdict, compile_properties, operators
from rasm.properties.loader import load_specification
from rasm.properties.operators import FutureOr, WindowOr

from .reference import Reference
from .strategies import (
    HEADER,
    ORDERED_LATE,
    UNITS,
    UNORDERED_LATE,
    bounds,
    count_comparisons,
    decimal_traces,
    formulas,
    numeric_formulas,
    traces,
)
from .test_semantics import horizon


def decided_at(spec, records, prop: int = 0) -> dict[int, tuple[int, bool]]:
    """For each record i: (the first k at which its verdict is decided, that verdict)."""
    first: dict[int, tuple[int, bool]] = {}
    for k in range(len(records)):
        values = Reference(spec, records[: k + 1]).verdicts(spec.properties[prop])
        for i, value in values.items():
            if value is not None and i not in first:
                first[i] = (k, value)
    return first


def emitted(text: str, records) -> dict[str, dict[int, tuple[int, object]]]:
    """Per property, each verdict given online: (the record whose step gave it, its value);
    those given by finish() at len(records)."""
    monitor = compile_properties(text)
    got: dict[str, dict[int, tuple[int, object]]] = {name: {} for name in monitor.properties}
    for k, (t, record) in enumerate(records):
        for verdict in monitor.step(t, record):
            assert verdict.index not in got[verdict.property], "a verdict was given twice"
            got[verdict.property][verdict.index] = (k, verdict.value)
    for verdict in monitor.finish():
        assert verdict.index not in got[verdict.property], "a verdict was given twice"
        got[verdict.property][verdict.index] = (len(records), verdict.value)
    return got


def assert_verdicts_come_when_decided(text: str, records) -> None:
    spec = load_specification(text)
    got = emitted(text, records)
    for number, prop in enumerate(spec.properties):
        decided = decided_at(spec, records, number)
        full = Reference(spec, records).verdicts(prop)
        mine = got[prop.name]
        assert set(mine) == set(full), (prop.name, text)
        for i, (at, value) in mine.items():
            assert value == full[i], (text, i)
            if i in decided:
                # given in the step of the very record that decided it
                assert (at, value) == decided[i], (text, i, at, decided[i])
            else:
                # never decided: given by finish(), inconclusive
                assert at == len(records) and value is None, (text, i)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(formulas(3), traces(max_size=14))
def test_every_verdict_comes_in_the_step_of_the_record_that_decides_it(formula, records):
    assert_verdicts_come_when_decided(HEADER + f"property p0: {formula}\n", records)


@pytest.mark.slow
@settings(max_examples=100, deadline=None)
@given(st.data())
def test_on_decimal_times_too(data):
    unit = data.draw(st.sampled_from(UNITS))
    formula = data.draw(formulas(3, unit=unit))
    records = data.draw(decimal_traces(unit, max_size=14))
    assert_verdicts_come_when_decided(HEADER + f"property p0: {formula}\n", records)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(st.lists(formulas(2), min_size=2, max_size=3), traces(max_size=12))
def test_several_properties_each_as_soon_as_decided(formulas_, records):
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    assert_verdicts_come_when_decided(text, records)


# ---------------------------------------------------------------- nested decisions


FUTURE = ["eventually[0, 1] p", "always[0, 1] q", "eventually[0.5, 2] q", "always[1, 2] r",
          "(p) until[0, 2] (q)", "(not q) until[1, 3] (p)"]


@st.composite
def late_operands(draw, depth: int) -> str:
    """Formulas whose operands are themselves late, combined every way the language allows:
    the values an operator gets come in any order."""
    if depth <= 0:
        return draw(st.sampled_from(FUTURE + ["p", "q", "r", "prev(p)", "once[0, 1] q"]))
    sub = late_operands(depth - 1)
    shape = draw(st.integers(0, 9))
    if shape <= 2:
        op = draw(st.sampled_from(["and", "or", "->"]))
        return f"({draw(sub)}) {op} ({draw(sub)})"
    if shape == 3:
        return f"not ({draw(sub)})"
    if shape <= 5:
        op = draw(st.sampled_from(["eventually", "always"]))
        return f"{op}{draw(bounds(False))} ({draw(sub)})"
    if shape == 6:
        op = draw(st.sampled_from(["once", "historically"]))
        return f"{op}{draw(bounds(True))} ({draw(sub)})"
    if shape == 7:
        return f"({draw(sub)}) until{draw(bounds(False))} ({draw(sub)})"
    if shape == 8:
        return f"({draw(sub)}) since{draw(bounds(True))} ({draw(sub)})"
    return f"prev({draw(sub)})"


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(late_operands(3), traces(max_size=14))
def test_operators_over_late_values_decide_as_soon_as_they_can(formula, records):
    assert_verdicts_come_when_decided(HEADER + f"property p0: {formula}\n", records)


def test_a_conjunction_is_false_as_soon_as_one_side_is():
    # SPEC's example: false at record 0 once q fails at 0.3 s, not when the eventually's
    # window ends (5 s later)
    monitor = compile_properties(
        "event p\nevent q\nproperty p0: (always[0, 0.3] q) and (eventually[0, 5] p)\n"
    )
    assert monitor.step(0.0, {"q": True}) == []
    assert monitor.step(0.1, {"q": True}) == []
    # q fails at 0.3: records 0 (t=0), 1 (t=0.1) and 2 (t=0.3) are false now
    assert sorted(monitor.step(0.3, {})) == [
        Verdict("p0", 0, 0.0, False), Verdict("p0", 1, 0.1, False), Verdict("p0", 2, 0.3, False),
    ]
    # q holds from 0.4 to 0.7, p at 0.8: record 3 is true there, at 0.8 (its always ends at 0.7)
    for t in (0.4, 0.5, 0.6, 0.7):
        assert monitor.step(t, {"q": True}) == []
    assert Verdict("p0", 3, 0.4, True) in monitor.step(0.8, {"p": True, "q": True})


# ---------------------------------------------------------------- forced by the records


def continuations(spec, records, k: int) -> list[list]:
    """Ways the trace r0 … rk may go on, each ending with a record beyond every window of
    r0 … rk: the trace's own continuation, none, and records on the 0.5 s grid (every bound
    and time here is on it) from t_k or from the next grid time on, one or two at each time
    (two: ``prev`` sees the new values there too), with every combination of constant p, q,
    r."""
    t_k = records[k][0]
    reach = max(horizon(p.formula) for p in spec.properties)
    close = (t_k + reach + 1, {})
    out = [[*records[k + 1:], close], [close]]
    for skip in (0, 1):
        grid = [t_k + 0.5 * n for n in range(skip, int(2 * reach) + 1)]
        for copies in (1, 2):
            for bits in range(8):
                values = {"p": bool(bits & 1), "q": bool(bits & 2), "r": bool(bits & 4)}
                out.append([*((t, dict(values)) for t in grid for _ in range(copies)), close])
    return out


@pytest.mark.slow
@settings(max_examples=120, deadline=None)
@given(formulas(2), traces(max_size=8))
def test_a_decided_verdict_is_the_same_for_every_continuation(formula, records):
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    given_at = emitted(text, records)["p0"]
    for i, (k, value) in given_at.items():
        if value is None or k == len(records):
            continue
        for rest in continuations(spec, records, k):
            trace = records[: k + 1] + rest
            assert Reference(spec, trace).verdicts(spec.properties[0])[i] == value, (
                formula, i, k, rest,
            )


@st.composite
def read_once(draw, depth: int, names: tuple[str, ...], ahead: bool = False) -> str:
    """A formula over booleans that reads each of ``names`` at most once, with no future
    operator inside another (see below); ``ahead``: inside a future operator (a signal or its
    negation)."""
    if ahead or depth <= 0 or len(names) == 1 or draw(st.integers(0, 3)) == 0:
        atom = names[0]
        if ahead:
            return draw(st.sampled_from([atom, f"not {atom}"]))
        if draw(st.booleans()):
            op = draw(st.sampled_from(["eventually", "always"]))
            return f"{op}{draw(bounds(False))} ({draw(read_once(0, names, True))})"
        return draw(st.sampled_from([atom, f"not {atom}", f"prev({atom})"]))
    shape = draw(st.integers(0, 4))
    split = draw(st.integers(1, len(names) - 1))
    if shape <= 1:
        left = draw(read_once(depth - 1, names[:split]))
        right = draw(read_once(depth - 1, names[split:]))
        return f"({left}) {draw(st.sampled_from(['and', 'or', '->']))} ({right})"
    if shape == 2:
        left = draw(read_once(0, names[:split], True))
        right = draw(read_once(0, names[split:], True))
        return f"({left}) until{draw(bounds(False))} ({right})"
    inner = draw(read_once(depth - 1, names))
    if shape == 3:
        return f"{draw(st.sampled_from(['once', 'historically']))}{draw(bounds(True))} ({inner})"
    return f"not ({inner})"


LOOKING_AHEAD = (
    st.permutations(["p", "q", "r"])
    .flatmap(lambda names: read_once(3, tuple(names)))
    .filter(lambda f: any(op in f for op in ("eventually", "always", "until")))
)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(LOOKING_AHEAD, traces(max_size=10))
def test_a_verdict_not_decided_yet_still_depends_on_the_continuation(formula, records):
    """Where each signal occurs once and no future operator lies inside another, the records
    before the one that decides a verdict leave it open: some continuation of them gives the
    other value.

    Beyond that fragment a verdict can be settled before its operators are: by logic alone
    where a signal occurs twice (``eventually[0, 1] p or not eventually[0, 1] p``), by a past
    operator at records still to come (``eventually[0, 1] (once[5, inf] p)`` is false in a
    trace's first four seconds: no record to come has one 5 s before it), or by where records
    can lie (``not always[0, 0.5] (prev(p) until[0.5, 0.5] q)`` after two records at 0 s, the
    first with p: the until's witness at 0.5 s would itself be a record of the always, where
    the until fails). The monitor decides each operator from its operands' values at the
    records that have come — SPEC §5's three-valued value over the trace so far — and gives
    such verdicts no earlier than that.
    """
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    for i, (k, value) in emitted(text, records)["p0"].items():
        if value is None or k == i or k == len(records):
            continue  # decided with its own record, or never
        outcomes = {
            Reference(spec, records[:k] + rest).verdicts(spec.properties[0])[i]
            for rest in continuations(spec, records, k - 1)
        }
        assert outcomes == {True, False}, (formula, i, k, outcomes)


# ---------------------------------------------------------------- offline


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(formulas(3), traces(max_size=14))
def test_offline_each_verdict_is_handed_out_once_it_and_those_before_are_decided(
    formula, records
):
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    decided = decided_at(spec, records)
    monitor = compile_properties(text)
    handed: list = []
    for k, record in enumerate(records):
        monitor.feed([record])
        first, values, _ = monitor.take(0)
        assert first == (monitor.starts[0] or 0) + len(handed)
        handed += values
        start = monitor.starts[0]
        if start is None:
            continue
        # record order: every record up to the last handed out is decided by now, the next
        # one is not
        assert all(decided[j][0] <= k for j in range(start, start + len(handed)))
        following = start + len(handed)
        assert following > k or following not in decided or decided[following][0] > k
    monitor.settle()
    handed += monitor.take(0)[1]
    assert handed == [v for _, v in sorted(Reference(spec, records).verdicts(
        spec.properties[0]).items())]



# ---------------------------------------------------------------- forgetting


@contextlib.contextmanager
def forgetting_at_once():
    """The windows and chains forget what they no longer need at every chance (they wait for a
    few hundred records, or batches of 64, otherwise): short traces then go through it too."""
    saved = WindowOr.TIDY, FutureOr.TIDY, operators.BATCH
    WindowOr.TIDY, FutureOr.TIDY, operators.BATCH = 1, 1, 0
    try:
        yield
    finally:
        WindowOr.TIDY, FutureOr.TIDY, operators.BATCH = saved


@st.composite
def late_values(draw):
    """Records at non-decreasing times and, per record, the step at which its operand value
    comes (at once, a few records later, or only at the end: then maybe inconclusive)."""
    gaps = draw(st.lists(st.sampled_from([0, 1, 1, 2, 3]), min_size=1, max_size=40))
    times = [sum(gaps[: k + 1]) for k in range(len(gaps))]
    n = len(times)
    arrivals: dict[int, list[tuple[int, object]]] = {}
    for u in range(n):
        value = draw(st.booleans())
        at = min(n, u + draw(st.sampled_from([0, 0, 0, 1, 2, 5, 40])))
        if at == n and draw(st.booleans()):
            value = None
        arrivals.setdefault(at, []).append((u, value))
    for values in arrivals.values():
        values[:] = draw(st.permutations(values))
    return times, arrivals


def _decisions(window, times, arrivals, flip=lambda v: v) -> dict[int, tuple[object, int]]:
    """Each output of ``window`` (a WindowOr or a FutureOr): (its value, the record at which
    it came, len(times) for the end)."""
    got: dict[int, tuple[object, int]] = {}
    queue: deque = deque()
    for k in range(len(times) + 1):
        values = arrivals.get(k, [])
        if isinstance(window, FutureOr):
            queue.extend((u, None, None, v) for u, v in values)
            if k < len(times):
                window.step(k, times[k], times[k], queue)
            else:
                window.finish(queue)
        else:
            if k < len(times):
                window.record(k, times[k], times[k])
            for u, v in values:
                window.put(u, v)
            if k == len(times):
                window.finish()
        while window.out:
            j, _, _, v = window.out.popleft()
            assert j not in got, "an output decided twice"
            got[j] = (flip(v), k)
    return got


@settings(max_examples=300, deadline=None)
@given(late_values(), st.sampled_from([0, 1, 2]), st.sampled_from([0, 1, 2, 5, 10]),
       st.booleans(), st.booleans(), st.sampled_from([1, 256]))
def test_future_or_decides_as_the_window_does(values, a, width, hit, negate, tidy):
    """FutureOr (eventually/always over late values) gives every output the value WindowOr's
    future window gives it, at the same record, whatever order the values come in, taking
    them negated (``hit`` False) and negating its outputs as asked, forgetting at once or not."""
    times, arrivals = values
    saved = FutureOr.TIDY, WindowOr.TIDY
    FutureOr.TIDY = WindowOr.TIDY = tidy
    try:
        expected = _decisions(WindowOr(False, a, a + width), times, arrivals)
        def k_not(v):
            return None if v is None else not v
        window = FutureOr(a, a + width, hit)
        if negate:
            window.negate()
        given_values = arrivals if hit else {k: [(u, k_not(v)) for u, v in values]
                                             for k, values in arrivals.items()}
        got = _decisions(window, times, given_values, k_not if negate else (lambda v: v))
    finally:
        FutureOr.TIDY, WindowOr.TIDY = saved
    assert got == expected


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.one_of(formulas(3), late_operands(3)), traces(max_size=30))
def test_forgetting_what_no_window_needs_changes_no_verdict(formula, records):
    with forgetting_at_once():
        assert_verdicts_come_when_decided(HEADER + f"property p0: {formula}\n", records)
        spec = load_specification(HEADER + f"property p0: {formula}\n")
        run = compile_properties(HEADER + f"property p0: {formula}\n").run(records)[0]
        expected = Reference(spec, records).verdicts(spec.properties[0])
        assert {run.start + k: v for k, v in enumerate(run.values)} == expected
        assert not run.errors


@st.composite
def aggregates_of_late_values(draw) -> str:
    """An aggregate over values that come late: in record order (``eventually p``) or not
    (``p and eventually q``)."""
    late = draw(st.sampled_from([
        "eventually[0, 1] p", "always[0.5, 2] q", "p and eventually[0, 2] q",
        "(eventually[0, 1] p) or (always[0, 1] r)", "prev(eventually[0, 1] q)",
    ]))
    bound = draw(bounds(True))
    shape = draw(st.integers(0, 2))
    if shape == 0:
        return f"count{bound}({late}) >= {draw(st.integers(0, 3))}"
    if shape == 1:
        op = draw(st.sampled_from(["sum", "avg", "min", "max"]))
        return f"{op}{bound}(x + count[0, 1]({late})) > {draw(st.sampled_from(['0.5', '1', '2']))}"
    return f"(once{bound} ({late})) and (count{bound}({late}) <= 2)"


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(aggregates_of_late_values(), traces(max_size=30))
def test_aggregates_over_late_values_agree_with_the_reference_forgetting_at_once(
    formula, records
):
    """Whatever order its operand's values come in, an aggregate's values are exact (when
    they come is tested above for values in record order; see AggregateStream)."""
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    expected = Reference(spec, records).verdicts(spec.properties[0])
    with forgetting_at_once():
        got = {i: value for i, (_, value) in emitted(text, records)["p0"].items()}
        run = compile_properties(text).run(records)[0]
    assert got == expected, formula
    assert {run.start + k: v for k, v in enumerate(run.values)} == expected


@pytest.mark.slow
@pytest.mark.parametrize("formula", [
    "(always[0, 3] q) and (eventually[0, 5] p)",
    "eventually[0, 5] (p and always[0, 2] q)",
    "once[0, 10] (eventually[0, 3] p)",
    "historically[1, inf] (eventually[0, 2] q)",
    "(eventually[0, 1] p) until[1, 4] (q or r)",
    "(always[0, 1] q) since[2, 6] (eventually[0, 1] p)",
    "count[1, 5](p and eventually[0, 2] q) >= 1",
    "prev(eventually[0, 3] p) -> r",
])
def test_a_long_trace_forgets_as_it_goes_and_agrees_with_the_reference(formula):
    """Hundreds of records: the windows forget in their ordinary batches along the way."""
    import random

    rng = random.Random(formula)
    records, t = [], 0.0
    for _ in range(700):
        t += rng.choice([0, 0.5, 0.5, 1])
        records.append((t, {name: rng.random() < 0.4 for name in ("p", "q", "r")}))
    text = HEADER.replace("input x: float\ninput y: int\n", "") + f"property p0: {formula}\n"
    spec = load_specification(text)
    expected = Reference(spec, records).verdicts(spec.properties[0])
    got = emitted(text, records)["p0"]
    assert {i: value for i, (_, value) in got.items()} == expected
    run = compile_properties(text).run(records)[0]
    assert {run.start + k: v for k, v in enumerate(run.values)} == expected and not run.errors


# ---------------------------------------------------------------- counts over late values


@st.composite
def with_count_comparisons(draw) -> str:
    """Count comparisons alone, or under other operators (their values come early, in any
    order, to the operators above)."""
    atom = draw(count_comparisons())
    shape = draw(st.integers(0, 4))
    if shape == 0:
        return atom
    if shape == 1:
        return f"not ({atom})"
    if shape == 2:
        return f"({atom}) {draw(st.sampled_from(['and', 'or', '->']))} ({draw(formulas(1))})"
    if shape == 3:
        return f"always{draw(bounds(False))} ({atom})"
    return f"once{draw(bounds(True))} ({atom})"


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(with_count_comparisons(), traces(max_size=14))
def test_a_count_comparison_is_decided_as_soon_as_the_count_range_fixes_it(formula, records):
    """``count[0, 5](eventually[0, 1] p) >= 3`` is true as soon as three of its window's
    values are known true, false as soon as too few can still be: the reference decides a
    comparison with a count from the range [known true, known true + not known yet]."""
    assert_verdicts_come_when_decided(HEADER + f"property p0: {formula}\n", records)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(count_comparisons(ORDERED_LATE + UNORDERED_LATE), traces(max_size=25))
def test_a_count_comparison_over_values_in_any_order_is_exact(formula, records):
    """Values that come out of record order enter the count in record order (a record may
    wait for an earlier one's value, see CountStream): its verdicts are still the
    reference's, and each early one is the verdict of the full trace."""
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    expected = Reference(spec, records).verdicts(spec.properties[0])
    with forgetting_at_once():
        got = {i: value for i, (_, value) in emitted(text, records)["p0"].items()}
        run = compile_properties(text).run(records)[0]
    assert got == expected, formula
    assert {run.start + k: v for k, v in enumerate(run.values)} == expected


def test_count_ranges_decide_the_example():
    text = "event p\nproperty enough: count[0, 5](eventually[0, 1] p) >= 3\n" \
        "property few: count[0, 5](eventually[0, 1] p) < 3\n"
    monitor = compile_properties(text)
    given: dict[tuple[str, int], tuple[int, bool]] = {}
    for k in range(8):
        for v in monitor.step(k * 0.5, {"p": k in (2, 3, 5)}):
            given[v.property, v.index] = (k, v.value)
    # record 2 (1.0 s): its window (0 s to 1.0 s) holds three records, each of which sees
    # p within 1 s: decided at 1.0 s, not when the last of them closes its window (2.0 s)
    assert given["enough", 2] == (2, True) and given["few", 2] == (2, False)
    # records 0 and 1 have windows of one and two records: never three, false at once
    assert given["enough", 0] == (0, False) and given["enough", 1] == (1, False)
    # record 4 (2.0 s): four of its window known true at 2.0 s (p at 1.0, 1.5)
    assert given["enough", 4] == (4, True)


# ---------------------------------------------------------------- the robustness interval


def intervals_and_verdicts(text: str, records):
    """Online with robustness and intervals: each verdict (the step that gave it, the verdict),
    and after each step the interval of every record whose robustness is not final."""
    monitor = compile_properties(text, robustness=True, intervals=True)
    given: dict[int, tuple[int, Verdict]] = {}
    seen: list[tuple[int, int, tuple[float, float]]] = []
    for k, (t, record) in enumerate(records):
        for verdict in monitor.step(t, record):
            given[verdict.index] = (k, verdict)
        seen += [(k, j, iv) for j, iv in monitor.intervals("p0").items()]
    for verdict in monitor.finish():
        given[verdict.index] = (len(records), verdict)
    return given, seen


LATE_AND_NUMERIC = st.one_of(formulas(3), numeric_formulas(3), with_count_comparisons())


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(LATE_AND_NUMERIC, traces(max_size=12))
def test_a_verdict_is_out_once_its_robustness_interval_excludes_zero(formula, records):
    """At every step, a record whose robustness interval lies above zero has its verdict out,
    true, and one whose interval lies below zero has it out, false: the boolean verdict comes
    no later than the interval excludes zero. The verdicts (and when they come) are the same
    with robustness and without, and each is the verdict the full trace gives."""
    text = HEADER + f"property p0: {formula}\n"
    spec = load_specification(text)
    full = Reference(spec, records).verdicts(spec.properties[0])
    given, seen = intervals_and_verdicts(text, records)
    for k, j, (lo, hi) in seen:
        if lo > 0 or hi < 0:
            assert j in given and given[j][0] <= k, (formula, j, k, (lo, hi))
            assert given[j][1].value is (lo > 0), (formula, j, (lo, hi), given[j])
    plain = emitted(text, records)["p0"]
    assert {j: (k, v.value) for j, (k, v) in given.items()} == plain, formula
    for j, (k, verdict) in given.items():
        assert verdict.value == full[j], (formula, j, k, verdict)


def test_the_interval_of_a_count_comparison_is_its_range():
    text = "event p\nproperty p0: count[0, 5](eventually[0, 1] p) >= 3\n"
    monitor = compile_properties(text, robustness=True, intervals=True)
    steps = [monitor.step(k * 0.5, {"p": k in (2, 3, 5)}) for k in range(5)]
    # record 4 (2.0 s): five records in its window, four known true (each sees p at 1.0 s
    # or 1.5 s within 1 s), one still open (2.0 s): the count is 4 or 5, count - 3 in [1, 2]
    (v,) = steps[4]
    assert (v.index, v.value, v.robustness) == (4, True, None)
    assert v.robustness_interval == (1.0, 2.0)
    assert monitor.intervals("p0") == {4: (1.0, 2.0)}
