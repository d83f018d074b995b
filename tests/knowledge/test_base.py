"""The Knowledge Manager's store: types, bounds, time order, bounded history, range queries."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import RasmError
from rasm.knowledge import Declaration, KnowledgeBase, KnowledgeError, Sample
from rasm.knowledge.values import make_check

from .support import VALUES, same, time_steps, times_from

SETTINGS = settings(max_examples=150, deadline=None)


# -- types ----------------------------------------------------------------------------------------


@SETTINGS
@given(st.sampled_from(sorted(VALUES)), st.data())
def test_every_value_of_a_declared_type_is_accepted_and_read_back(kind, data):
    value = data.draw(VALUES[kind])
    kb = KnowledgeBase()
    kb.declare("k", kind)
    sample = kb.register_knowledge("k", value, 1.0)
    assert same(sample.value, value)
    assert same(kb.read_knowledge("k"), value)
    assert kb.read_sample("k") == sample or math.isnan(sample.value)  # NaN != NaN


def _accepted(kind: str, value: object) -> bool:
    """What each type takes: exact type; an int for a float; bool is never a number."""
    if kind == "float":
        return type(value) in (int, float)
    return type(value) is {"int": int, "bool": bool, "str": str}[kind]


@SETTINGS
@given(
    st.sampled_from(["float", "int", "bool", "str"]),
    st.sampled_from(sorted(VALUES)),
    st.data(),
)
def test_a_value_of_the_wrong_type_is_refused_naming_key_expected_and_got(kind, other, data):
    value = data.draw(VALUES[other])
    kb = KnowledgeBase()
    kb.declare("speed", kind)
    if _accepted(kind, value):
        kb.register_knowledge("speed", value, 0.0)
        return
    with pytest.raises(KnowledgeError) as caught:
        kb.register_knowledge("speed", value, 0.0)
    message = str(caught.value)
    assert "'speed'" in message
    assert f"expected {kind}" in message
    assert f"got {type(value).__name__}" in message
    assert kb.read_sample("speed") is None  # nothing was stored


def test_ints_are_accepted_for_float_and_stored_as_float():
    kb = KnowledgeBase()
    kb.declare("v", "float")
    assert kb.register_knowledge("v", 3, 0.0).value == 3.0
    assert type(kb.read_knowledge("v")) is float


@pytest.mark.parametrize("kind", ["int", "float"])
def test_bool_is_not_a_number(kind):
    kb = KnowledgeBase()
    kb.declare("n", kind)
    with pytest.raises(KnowledgeError, match=f"'n': expected {kind}, got bool True"):
        kb.register_knowledge("n", True, 0.0)


def test_json_values_are_stored_as_json_gives_them_back_and_copied():
    kb = KnowledgeBase()
    kb.declare("plan", "json")
    plan = {"steps": ("a", "b"), "speeds": [0.1, 0.2]}
    kb.register_knowledge("plan", plan, 0.0)
    plan["speeds"].append(9.9)  # the caller's later change must not rewrite history
    assert kb.read_knowledge("plan") == {"steps": ["a", "b"], "speeds": [0.1, 0.2]}


@pytest.mark.parametrize("value", [{1, 2}, b"bytes", object(), {"a": float}, [1, {2}]])
def test_a_value_that_is_not_json_is_refused_with_a_hint(value):
    kb = KnowledgeBase()
    kb.declare("plan", "json")
    with pytest.raises(KnowledgeError, match=r"'plan': expected a JSON value, got .*tolist"):
        kb.register_knowledge("plan", value, 0.0)


@pytest.mark.parametrize(
    ("value", "kind"),
    [(True, "bool"), (3, "int"), (2.5, "float"), ("idle", "str"), ([1, 2], "json"), (None, "json")],
)
def test_an_undeclared_key_takes_its_type_from_its_first_value(value, kind):
    kb = KnowledgeBase(default_history=7)
    kb.register_knowledge("x", value, 0.0)
    assert kb.declaration("x") == Declaration("x", kind, 7)


def test_an_inferred_type_is_then_enforced_with_a_hint_to_declare():
    kb = KnowledgeBase()
    kb.register_knowledge("count", 0, 0.0)
    with pytest.raises(KnowledgeError, match="'count': expected int, got float 0.5"):
        kb.register_knowledge("count", 0.5, 1.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"type": "double"}, "unknown type 'double'; use one of float, int, bool, str, json"),
        ({"history": 0}, "history must be a whole number >= 1"),
        ({"history": 2.5}, "history must be a whole number >= 1"),
        ({"type": "str", "minimum": 0}, "minimum applies only to float and int keys"),
        ({"minimum": 2, "maximum": 1}, "minimum 2 is above maximum 1"),
        ({"maximum": float("nan")}, "maximum must be a number"),
    ],
)
def test_bad_declarations_are_refused(kwargs, message):
    kb = KnowledgeBase()
    with pytest.raises(KnowledgeError, match=message.replace("(", r"\(")):
        kb.declare("k", kwargs.pop("type", "float"), **kwargs)


def test_knowledge_error_is_a_rasm_error():
    assert issubclass(KnowledgeError, RasmError)


# -- bounds ---------------------------------------------------------------------------------------


@SETTINGS
@given(
    st.floats(allow_nan=False, min_value=-100, max_value=100),
    st.floats(allow_nan=False, min_value=0, max_value=100),
    st.floats(),
)
def test_values_outside_declared_bounds_are_refused(lo, width, value):
    kb = KnowledgeBase()
    kb.declare("v", "float", minimum=lo, maximum=lo + width)
    if lo <= value <= lo + width:
        assert kb.register_knowledge("v", value, 0.0).value == value
    else:  # NaN included: it is in no range; worded as Telegraf words it (one check for both)
        with pytest.raises(
            KnowledgeError, match="'v': .* is (below the declared min|above the declared max)imum"
        ):
            kb.register_knowledge("v", value, 0.0)


# -- time -----------------------------------------------------------------------------------------


def test_time_may_repeat_but_not_go_back_per_key():
    kb = KnowledgeBase()
    kb.register_knowledge("a", 1.0, 5.0)
    kb.register_knowledge("a", 2.0, 5.0)
    kb.register_knowledge("b", 1.0, 1.0)  # another key has its own clock order
    with pytest.raises(KnowledgeError, match="'a': time 4.0 is older than its last sample at 5.0"):
        kb.register_knowledge("a", 3.0, 4.0)
    assert kb.read_knowledge("a") == 2.0


@pytest.mark.parametrize("time", [float("nan"), float("inf"), float("-inf"), "1.0", True, None])
def test_a_time_that_is_not_a_finite_number_is_refused(time):
    kb = KnowledgeBase()
    with pytest.raises(KnowledgeError, match="'a': time"):
        kb.register_knowledge("a", 1.0, time)
    assert kb.read_sample("a") is None


def test_int_times_become_float_seconds():
    kb = KnowledgeBase()
    assert kb.register_knowledge("a", 1, 3) == Sample(3.0, 1)
    assert type(kb.read_sample("a").time) is float


# -- bounded history and range queries ------------------------------------------------------------


@SETTINGS
@given(st.integers(1, 12), st.lists(st.tuples(time_steps, st.integers()), max_size=60))
def test_bounded_history_keeps_exactly_the_last_n(n, writes):
    kb = KnowledgeBase()
    kb.declare("k", "int", history=n)
    written = []
    for time, (_, value) in zip(times_from([s for s, _ in writes]), writes, strict=True):
        written.append(kb.register_knowledge("k", value, time))
        assert kb.history("k") == written[-n:]  # after every write: across each ring wrap
        assert kb.read_sample("k") == written[-1]
    assert len(kb.history("k")) == min(n, len(writes))


def _brute(samples, last, since, until):
    chosen = [
        s
        for s in samples
        if (since is None or s.time >= since) and (until is None or s.time <= until)
    ]
    return chosen if last is None else chosen[max(0, len(chosen) - last) :]


bound = st.none() | st.sampled_from([-1.0, 0.0, 0.5, 1.0, 2.0, 3.25, 5.0, 100.0])


@SETTINGS
@given(
    st.integers(1, 10),
    st.lists(time_steps, max_size=40),
    st.lists(st.tuples(st.none() | st.integers(0, 12), bound, bound), min_size=1, max_size=5),
)
def test_range_queries_equal_a_brute_force_filter(n, steps, queries):
    kb = KnowledgeBase()
    kb.declare("k", "int", history=n)
    written = []
    for i, time in enumerate(times_from(steps)):
        written.append(kb.register_knowledge("k", i, time))
        for last, since, until in queries:  # queries at every fill level of the ring
            got = kb.history("k", last=last, since=since, until=until)
            assert got == _brute(written[-n:], last, since, until)


def test_history_of_an_unknown_key_is_empty_and_bad_last_is_refused():
    kb = KnowledgeBase()
    assert kb.history("nothing") == []
    assert kb.read_knowledge("nothing", default=4) == 4
    assert kb.read_sample("nothing") is None
    with pytest.raises(KnowledgeError, match="last must be a whole number >= 0"):
        kb.history("nothing", last=-1)


@SETTINGS
@given(
    st.integers(1, 8),
    st.integers(1, 8),
    st.lists(st.integers(-5, 5), max_size=20),
)
def test_redeclaring_resizes_keeping_the_last_samples(before, after, values):
    kb = KnowledgeBase()
    kb.declare("k", "int", history=before)
    written = [kb.register_knowledge("k", v, float(i)) for i, v in enumerate(values)]
    kb.declare("k", "int", history=after)
    assert kb.history("k") == written[-before:][-after:]
    more = kb.register_knowledge("k", 0, 100.0)
    assert kb.history("k") == (written[-before:] + [more])[-after:]


def test_redeclaring_int_as_float_converts_held_samples():
    kb = KnowledgeBase()
    kb.register_knowledge("v", 1, 0.0)
    kb.declare("v", "float")
    assert kb.history("v") == [Sample(0.0, 1.0)]
    assert type(kb.read_knowledge("v")) is float


def test_redeclaring_to_a_type_held_samples_do_not_fit_is_refused_and_changes_nothing():
    kb = KnowledgeBase()
    kb.register_knowledge("v", 1.5, 0.0)
    with pytest.raises(KnowledgeError, match="cannot declare 'v' as int"):
        kb.declare("v", "int")
    assert kb.declaration("v").type == "float"
    assert kb.history("v") == [Sample(0.0, 1.5)]


def test_keys_snapshot_and_declarations():
    kb = KnowledgeBase()
    kb.declare("declared", "str")
    kb.register_knowledge("b", True, 0.0)
    kb.register_knowledge("a", 2.5, 0.0)
    kb.register_knowledge("a", 3.5, 1.0)
    assert kb.keys() == ["declared", "b", "a"]
    assert kb.snapshot() == {"b": True, "a": 3.5}  # only keys that have a value
    assert set(kb.declarations()) == {"declared", "b", "a"}
    assert kb.declaration("declared") == Declaration("declared", "str")  # no sample yet
    assert "declared" in kb and "other" not in kb


def test_load_samples_checks_everything_first_and_does_not_notify():
    kb = KnowledgeBase()
    kb.declare("v", "float", history=2)
    seen = []
    kb.subscribe(lambda key, sample: seen.append(key))
    with pytest.raises(KnowledgeError):
        kb.load_samples("v", [Sample(0.0, 1.0), Sample(1.0, "bad")])
    assert kb.history("v") == []
    assert kb.load_samples("v", [Sample(0.0, 1), Sample(1.0, 2.0), Sample(2.0, 3.0)]) == 3
    assert kb.history("v") == [Sample(1.0, 2.0), Sample(2.0, 3.0)]
    assert seen == []


# -- batches --------------------------------------------------------------------------------------

BATCH_KEYS = {
    "speed": ("float", 0.0, 10.0),
    "count": ("int", None, None),
    "on": ("bool", None, None),
}
BATCH_VALUES = st.one_of(
    VALUES["float"], VALUES["int"], VALUES["bool"], st.sampled_from([-1.0, 5.0, 11.0, "x", None])
)
BATCH_TIMES = st.sampled_from([0.0, 1.0, 1.0, 2.5, -1.0, math.nan, math.inf, 3, True, "now"])


def _declared_base() -> tuple[KnowledgeBase, list]:
    kb = KnowledgeBase()
    for key, (kind, lo, hi) in BATCH_KEYS.items():
        kb.declare(key, kind, minimum=lo, maximum=hi)
    seen: list = []
    kb.subscribe(lambda key, sample: seen.append((key, sample)))
    return kb, seen


@SETTINGS
@given(
    st.lists(
        st.tuples(
            st.dictionaries(st.sampled_from([*BATCH_KEYS, "new"]), BATCH_VALUES, max_size=4),
            BATCH_TIMES,
        ),
        max_size=6,
    )
)
def test_a_batch_is_each_value_registered_one_after_the_other(batches):
    batched, batched_seen = _declared_base()
    single, single_seen = _declared_base()
    for values, time in batches:
        refused = batched.register_values(values, time)
        expected = {}
        for key, value in values.items():
            try:
                single.register_knowledge(key, value, time)
            except Exception as exc:
                expected[key] = exc
        assert list(refused) == list(expected)
        assert [(type(e), str(e)) for e in refused.values()] == [
            (type(e), str(e)) for e in expected.values()
        ]
        stored = [key for key in values if key not in refused]
        assert same(
            {key: batched.read_knowledge(key) for key in stored},
            {key: single.read_knowledge(key) for key in stored},
        )
    assert same([list(s) for _, s in batched_seen], [list(s) for _, s in single_seen])
    assert [k for k, _ in batched_seen] == [k for k, _ in single_seen]
    # what is handed out is a Sample
    assert all(type(s) is Sample for _, s in batched_seen)
    for key in single.keys():
        history = batched.history(key)
        assert same([list(s) for s in history], [list(s) for s in single.history(key)])
        assert all(type(s) is Sample for s in history)
        assert type(batched.read_sample(key)) is Sample or not history
        assert batched.read_sample(key) == (history[-1] if history else None)


def test_a_batch_subscriber_gets_each_registration_call_at_once():
    kb = KnowledgeBase()
    kb.declare("speed", "float", minimum=0.0)
    batches, values = [], []
    kb.subscribe_batches(batches.append)
    kb.subscribe(lambda key, sample: values.append((key, sample)))
    refused = kb.register_values({"speed": -1.0, "other": 2.0, "count": 3}, 1.0)
    kb.register_knowledge("speed", 0.5, 2.0)
    assert kb.register_values({"speed": -2.0}, 3.0).keys() == {"speed"}  # nothing stored
    assert list(refused) == ["speed"]
    stored = [("other", Sample(1.0, 2.0)), ("count", Sample(1.0, 3))]
    assert batches == [stored, [("speed", Sample(2.0, 0.5))]]
    assert values == [*stored, ("speed", Sample(2.0, 0.5))]


def test_a_subscriber_failing_in_a_batch_fails_neither_the_batch_nor_the_others():
    kb = KnowledgeBase()
    seen = []
    kb.subscribe(lambda key, sample: 1 / 0)
    kb.subscribe(lambda key, sample: seen.append(key))
    assert kb.register_values({"a": 1.0, "b": "x"}, 0.0) == {}
    assert seen == ["a", "b"]


# -- reads and writes agree ----------------------------------------------------------------


def _same(a, b) -> bool:
    """Equal and of the same type, a nan equal to a nan."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and math.isnan(a):
        return math.isnan(b)
    return a == b


READ_KEYS = st.sampled_from(["a", "b", "c", "missing"])


@settings(max_examples=300, deadline=None, database=None)
@given(
    st.lists(st.tuples(READ_KEYS, st.floats(-10, 10) | st.booleans() | st.text(max_size=3))),
    st.lists(READ_KEYS, max_size=5),
    st.none() | st.integers(),
)
def test_read_values_is_read_knowledge_of_each_key(writes, keys, default):
    kb = KnowledgeBase(default_history=3)
    for time, (key, value) in enumerate(writes):
        try:
            kb.register_knowledge(key, value, float(time))
        except Exception:  # a value of another type than the key's first: refused, as ever
            pass
    assert kb.read_values(keys, default) == {k: kb.read_knowledge(k, default) for k in keys}


BOUNDS = st.none() | st.integers(-5, 5) | st.floats(-5, 5) | st.sampled_from([-math.inf, math.inf])


ANY_VALUE = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(-(2**1100), 2**1100)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=3)
    | st.lists(st.integers(), max_size=2)
)


@settings(max_examples=300, deadline=None, database=None)
@given(st.sampled_from(["float", "int", "bool", "str", "json"]), BOUNDS, BOUNDS, ANY_VALUE)
def test_a_stored_value_is_what_its_declarations_check_makes_of_it(kind, lo, hi, value):
    numeric = kind in ("float", "int")
    if numeric and lo is not None and hi is not None and lo > hi:
        lo, hi = hi, lo
    decl = Declaration("k", kind, minimum=lo if numeric else None, maximum=hi if numeric else None)
    kb = KnowledgeBase()
    kb.declare("k", kind, minimum=decl.minimum, maximum=decl.maximum)
    try:
        expected = make_check(decl)(value)
    except KnowledgeError as exc:
        with pytest.raises(KnowledgeError) as raised:
            kb.register_knowledge("k", value, 1.0)
        assert str(raised.value) == str(exc)
        assert kb.register_values({"k": value}, 1.0)["k"].args == exc.args
        return
    assert _same(kb.register_knowledge("k", value, 1.0).value, expected)
    assert kb.register_values({"k": value}, 2.0) == {}
    assert _same(kb.read_knowledge("k"), expected)


# one key's life: writes (many, so that the oldest are dropped several times over), reads of
# every kind, a re-declaration with another history, a restore of samples in bulk
OP = st.one_of(
    st.tuples(st.just("write"), st.integers(1, 12)),
    st.tuples(st.just("declare"), st.integers(1, 9)),
    st.tuples(st.just("load"), st.integers(0, 12)),
)


@settings(max_examples=300, deadline=None, database=None)
@given(st.integers(1, 9), st.lists(OP, min_size=1, max_size=12))
def test_a_key_holds_its_last_history_samples_through_many_writes(history, ops):
    kb = KnowledgeBase()
    kb.declare("x", "float", history=history)
    held: list[Sample] = []  # what the key holds: its last `history` samples
    now = 0.0
    for op, n in ops:
        if op == "declare":  # a new history keeps the newest samples held
            history = n
            kb.declare("x", "float", history=history)
            held = held[-history:]
        else:
            fresh = [Sample(now + i, float(len(held) + i)) for i in range(n)]
            now += n
            if op == "write":
                for sample in fresh:
                    assert kb.register_knowledge("x", sample.value, sample.time) == sample
            else:
                assert kb.load_samples("x", fresh) == n
            held = (held + fresh)[-history:]
        assert kb.history("x") == held
        assert kb.read_sample("x") == (held[-1] if held else None)
        assert kb.read_knowledge("x", "none") == (held[-1].value if held else "none")
        assert kb.read_values(["x"], "none") == {"x": held[-1].value if held else "none"}
        assert kb.snapshot() == ({"x": held[-1].value} if held else {})
        for last in (None, 1, 3):
            for since in (None, now - 4.5, now - 3.0):
                for until in (None, now - 2.0, now - 1.5):
                    want = [
                        s for s in held
                        if (since is None or s.time >= since)
                        and (until is None or s.time <= until)
                    ]
                    want = want if last is None else want[max(0, len(want) - last) :]
                    assert kb.history("x", last=last, since=since, until=until) == want
        # a time before the newest sample held is refused, whatever was dropped before it
        if held:
            assert kb.register_values({"x": 0.0}, held[-1].time - 0.5) != {}
