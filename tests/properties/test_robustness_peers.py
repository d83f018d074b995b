"""Robustness against peer monitors: rtamt on the past fragment and on until (discrete time,
every record), mstlo on bounded-future always/eventually at every record whose window the
trace covers. Times are 0, 1, 2, … (a record per time unit) and every record sets every
signal."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties

from .test_peers import PROPS, to_rtamt, tree
from .test_peers import to_rasm as tree_in_rasm

rtamt = pytest.importorskip("rtamt")
HEADER = "".join(f"input {p}: float\n" for p in PROPS)
values = st.sampled_from([-1.0, 0.0, 0.25, 0.5, 0.75, 1.5])
rows = st.lists(st.tuples(values, values, values), min_size=2, max_size=25)  # rtamt: two or more


def to_rasm(node) -> str:
    """The tree in rasm's language, each atom ``p >= 0.5`` as in :func:`to_rtamt`."""
    return tree_in_rasm(node, atom=lambda name: f"({name} >= 0.5)")


def rasm_robustness(formula: str, data) -> list:
    monitor = compile_properties(HEADER + f"property f: {formula}\n", robustness=True)
    (run,) = monitor.run([(t, dict(zip(PROPS, row, strict=True))) for t, row in enumerate(data)])
    return run.robustness


def rtamt_robustness(node, data) -> list[float]:
    spec = rtamt.StlDiscreteTimeSpecification()
    for name in PROPS:
        spec.declare_var(name, "float")
    spec.spec = rtamt_text(node)
    spec.parse()
    series = {"time": list(range(len(data)))}
    for k, name in enumerate(PROPS):
        series[name] = [row[k] for row in data]
    return [r for _, r in spec.evaluate(series)]


def rtamt_text(node) -> str:
    """:func:`to_rtamt`, with unbounded past operators written without a bound."""
    kind = node[0]
    if kind in ("once", "historically", "since") and node[1] is None:
        if kind == "since":
            return f"({rtamt_text(node[2])} since {rtamt_text(node[3])})"
        return f"({kind} {rtamt_text(node[2])})"
    if kind == "atom":
        return to_rtamt(node)
    if kind == "not":
        return f"(not {rtamt_text(node[1])})"
    if kind == "implies":
        return f"((not {rtamt_text(node[1])}) or {rtamt_text(node[2])})"
    if kind in ("and", "or"):
        return f"({rtamt_text(node[1])} {kind} {rtamt_text(node[2])})"
    b = f"[{node[1][0]}:{node[1][1]}]"
    if kind in ("since", "until"):
        return f"({rtamt_text(node[2])} {kind}{b} {rtamt_text(node[3])})"
    return f"({kind}{b} {rtamt_text(node[2])})"


def same(a: float, b: float) -> bool:
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-9


@settings(max_examples=150, deadline=None)
@given(tree(3, future=False), rows)
def test_past_robustness_agrees_with_rtamt(node, data):
    ours = rasm_robustness(to_rasm(node), data)
    theirs = rtamt_robustness(node, data)
    assert all(same(a, b) for a, b in zip(ours, theirs, strict=True)), (to_rasm(node), ours,
                                                                       theirs)


@settings(max_examples=100, deadline=None)
@given(st.tuples(st.integers(0, 3), st.integers(1, 4)), rows)
def test_until_robustness_agrees_with_rtamt(bounds, data):
    low, width = bounds
    node = ("until", (low, low + width), ("atom", "p"), ("atom", "q"))
    ours = rasm_robustness(to_rasm(node), data)
    theirs = rtamt_robustness(node, data)
    for k, r in enumerate(ours):
        if r is not None:  # the window is covered: rtamt's offline value is final there
            assert same(r, theirs[k]), (k, ours, theirs)


mstlo = pytest.importorskip("mstlo_python")


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["always", "eventually"]), st.integers(0, 3), st.integers(0, 4),
       st.sampled_from(["always", "eventually", None]), rows)
def test_bounded_future_robustness_agrees_with_mstlo(outer, low, width, inner, data):
    b = f"[{low}, {low + width}]"
    atom_rasm, atom_mstlo = "p > 0.5", "p > 0.5"
    if inner is not None:
        atom_rasm = f"{inner}[0, 2] (q < 0.5)"
        atom_mstlo = f"{'G' if inner == 'always' else 'F'}[0, 2](q < 0.5)"
        atom_rasm = f"(p > 0.5) -> {atom_rasm}"
        atom_mstlo = f"(p > 0.5) -> {atom_mstlo}"
    ours = rasm_robustness(f"{outer}{b} ({atom_rasm})", data)
    op = "G" if outer == "always" else "F"
    monitor = mstlo.Monitor(mstlo.parse_formula(f"{op}{b}({atom_mstlo})"),
                            semantics="DelayedQuantitative")
    steps = [(name, row[k], float(t)) for t, row in enumerate(data)
             for k, name in enumerate(PROPS) if name in ("p", "q")]
    theirs = dict(monitor.update_batch(steps).verdicts())
    for t, r in enumerate(ours):
        if r is not None and float(t) in theirs:
            assert same(r, theirs[float(t)]), (t, ours, theirs)
