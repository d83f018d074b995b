"""The knowledge store's ring and batch writes give what a straightforward store gives.

The reference below is the store written plainly (a list of samples per key, every value
checked unless it is of the declared class exactly and in range, the last ``history`` kept,
queries by filtering): the ring (``_Series``) and ``register_values``' direct path must store,
refuse (with the same error), answer and hand out exactly what it does, for any values and
times, across every wrap of the ring.
"""

from __future__ import annotations

import math
import sys
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.knowledge.base import EXACT_CLASS, KnowledgeBase, Sample
from rasm.knowledge.values import Declaration, infer_type, make_check

SETTINGS = settings(max_examples=300, deadline=None, database=None)


class ClaimsFloat:
    """An object that says it is a float (``__class__``) and compares like 1.5."""

    @property  # type: ignore[misc]
    def __class__(self) -> type:  # noqa: D401
        return float

    def __le__(self, other: Any) -> bool:
        return 1.5 <= other

    def __ge__(self, other: Any) -> bool:
        return 1.5 >= other

    def __float__(self) -> float:
        return 1.5

    def __repr__(self) -> str:
        return "ClaimsFloat()"


CLAIMS_FLOAT = ClaimsFloat()


class _ReferenceStore:
    """The store as it is specified, written plainly."""

    def __init__(self, default_history: int) -> None:
        self.default_history = default_history
        self.decls: dict[str, Declaration] = {}
        self.samples: dict[str, list[Sample]] = {}

    def declare(self, key: str, kind: str, history: int, lo: Any, hi: Any) -> None:
        self.decls[key] = Declaration(key, kind, history, lo, hi)
        self.samples[key] = []

    def register(self, key: str, value: Any, time: Any) -> Sample:
        decl = self.decls.get(key)
        if decl is None:
            decl = self.decls[key] = Declaration(key, infer_type(value), self.default_history)
            self.samples[key] = []
        exact = EXACT_CLASS.get(decl.type)
        numeric = decl.type in ("float", "int")
        lo = -math.inf if decl.minimum is None else decl.minimum
        hi = math.inf if decl.maximum is None else decl.maximum
        # taken as it is: the declared class exactly (as the value says) and, numbers, in range
        if not (value.__class__ is exact and (not numeric or lo <= value <= hi)):
            value = make_check(decl)(value)
        if type(time) is not float:
            time = KnowledgeBase._time(key, time)
        held = self.samples[key]
        last = held[-1].time if held else -sys.float_info.max
        if not last <= time < math.inf:
            raise KnowledgeBase._bad_time(key, time, last)
        sample = Sample(time, value)
        held.append(sample)
        del held[: -decl.history]
        return sample

    def history(self, key: str, last: Any, since: Any, until: Any) -> list[Sample]:
        chosen = [
            s
            for s in self.samples.get(key, [])
            if (since is None or s.time >= since) and (until is None or s.time <= until)
        ]
        return chosen if last is None else chosen[max(0, len(chosen) - last) :]


KEYS = ["f", "i", "b", "s", "j", "new"]  # the last one is never declared: inferred
VALUE = st.one_of(
    st.floats(-3, 3),
    st.sampled_from([math.nan, math.inf, -math.inf, -0.0, 2**70, True, False, None]),
    st.integers(-3, 3),
    st.text(max_size=2),
    st.lists(st.integers(0, 2), max_size=2),
    st.just(CLAIMS_FLOAT),
)
# a batch's time: a step from the latest one (mostly forward, sometimes back, often a tie) or
# an odd time (not finite, an int, not a number)
STEP = st.sampled_from([0.0, 0.25, 0.5, 1.0, 1.0, -0.25, -1.0])
ODD_TIME = st.sampled_from([math.nan, math.inf, -math.inf, 2, "soon"])
# per key, mostly a value it takes (so that rings fill and wrap), else any value
GOOD = {
    "f": st.floats(-1, 2),
    "i": st.integers(-1, 2),
    "b": st.booleans(),
    "s": st.text(max_size=2),
    "j": st.lists(st.integers(0, 2), max_size=2),
    "new": st.floats(-3, 3),
}
VALUES = st.fixed_dictionaries({}, optional={k: GOOD[k] | GOOD[k] | VALUE for k in KEYS})
BATCH = st.tuples(VALUES, STEP | STEP | ODD_TIME)
BOUND = st.none() | st.sampled_from([-1.0, 0.0, 1.5, 2])


def _outcome(call) -> Any:
    try:
        return ("ok", call())
    except Exception as exc:
        return (type(exc), str(exc))


def _same(a: Any, b: Any) -> bool:
    """Equal and of the same type all the way down (a nan equal to a nan)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    return a == b


@SETTINGS
@given(
    st.integers(1, 4),
    st.tuples(BOUND, BOUND),
    st.lists(BATCH, max_size=16),
    st.booleans(),
)
def test_batches_and_single_writes_store_what_the_reference_store_stores(
    history, bounds, batches, one_by_one
):
    lo, hi = sorted(bounds, key=lambda b: -math.inf if b is None else b)
    kb, ref = KnowledgeBase(default_history=history), _ReferenceStore(history)
    for key, kind in zip("fibsj", ["float", "int", "bool", "str", "json"], strict=True):
        numeric = kind in ("float", "int")
        kb.declare(key, kind, history=history, minimum=lo if numeric else None,
                   maximum=hi if numeric else None)
        ref.declare(key, kind, history, lo if numeric else None, hi if numeric else None)
    heard: list[tuple[str, Sample]] = []
    kb.subscribe(lambda key, sample: heard.append((key, sample)))
    expected_heard: list[tuple[str, Sample]] = []
    now = 0.0
    for values, step in batches:
        if type(step) is float and math.isfinite(step):
            time = now = now + step
        else:
            time = step
        expected = {key: _outcome(lambda k=key, v=value, t=time: ref.register(k, v, t))
                    for key, value in values.items()}
        expected_heard += [(key, got[1]) for key, got in expected.items() if got[0] == "ok"]
        if one_by_one:
            got = {key: _outcome(lambda k=key, v=value, t=time: kb.register_knowledge(k, v, t))
                   for key, value in values.items()}
        else:
            into: dict[str, Any] = {}
            refused = kb.register_values(values, time, into=into)
            got = {key: (type(refused[key]), str(refused[key])) if key in refused
                   else ("ok", Sample(time if type(time) is float else float(time), into[key]))
                   for key in values}
        assert _same(got, expected)
        for key in KEYS:
            assert _same(kb.history(key), ref.history(key, None, None, None))
            held = ref.samples.get(key) or []
            assert _same(kb.read_sample(key), held[-1] if held else None)
            assert _same(kb.read_knowledge(key, "none"), held[-1].value if held else "none")
            # range bounds on, just before and just after every time held (a wrap included)
            bounds = sorted({s.time + d for s in held for d in (-0.125, 0.0, 0.125)})
            for bound in bounds:
                for last in (None, 1, 2):
                    for since, until in ((bound, None), (None, bound), (held[0].time, bound)):
                        got = kb.history(key, last=last, since=since, until=until)
                        assert _same(got, ref.history(key, last, since, until))
    assert _same(heard, expected_heard)


def test_a_value_that_says_it_is_a_float_is_taken_as_it_is_when_in_range():
    # (the fast tests read type() first, then __class__: what the object says still decides)
    kb = KnowledgeBase()
    kb.declare("f", "float", minimum=0.0, maximum=2.0)
    assert kb.register_values({"f": CLAIMS_FLOAT}, 1.0) == {}
    assert kb.read_knowledge("f") is CLAIMS_FLOAT


# one key's life: writes (many, so that the oldest are dropped several times over), reads of
# every kind, a re-declaration with another history, a restore of samples in bulk
OP = st.one_of(
    st.tuples(st.just("write"), st.integers(1, 12)),
    st.tuples(st.just("declare"), st.integers(1, 9)),
    st.tuples(st.just("load"), st.integers(0, 12)),
)


@SETTINGS
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
