"""Differential tests against peer monitors: reelay (past MTL) and rtamt (bounded-future STL).

Both peers run in discrete time (a record per time unit), so rasm gets times 0, 1, 2, …; every
record sets every proposition, so there is no warm-up. Zero-width windows are avoided for
reelay (it handles them oddly). rtamt's offline ``evaluate`` cuts windows at the end of the
trace, so only the records where rasm's verdict is decided (not inconclusive) are compared.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.properties import compile_properties

reelay = pytest.importorskip("reelay")
rtamt = pytest.importorskip("rtamt")

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "monitors_timescales.py"
_SPEC = importlib.util.spec_from_file_location("monitors_timescales", _PATH)
timescales = importlib.util.module_from_spec(_SPEC)
sys.modules.setdefault("monitors_timescales", timescales)
_SPEC.loader.exec_module(timescales)

PROPS = ("p", "q", "r")
HEADER = "".join(f"input {p}: bool\n" for p in PROPS)


# ----------------------------------------------------------------- formulas as small trees
@st.composite
def bound(draw, zero_width: bool):
    low = draw(st.integers(0, 3))
    high = low + draw(st.integers(0 if zero_width else 1, 4))
    return (low, high)


@st.composite
def tree(draw, depth: int, future: bool):
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return ("atom", draw(st.sampled_from(PROPS)))
    sub = tree(depth - 1, future)
    if future:
        ops = ["not", "and", "or", "implies", "eventually", "always", "until"]
    else:
        ops = ["not", "and", "or", "implies", "once", "historically", "since"]
    op = draw(st.sampled_from(ops))
    if op == "not":
        return ("not", draw(sub))
    if op in ("and", "or", "implies"):
        return (op, draw(sub), draw(sub))
    unbounded = not future and draw(st.integers(0, 3)) == 0
    b = None if unbounded else draw(bound(zero_width=future))
    if op in ("since", "until"):
        return (op, b, draw(sub), draw(sub))
    return (op, b, draw(sub))


def to_rasm(node, atom=str) -> str:
    """The tree in rasm's language, each atom as ``atom`` writes its name."""
    kind = node[0]
    if kind == "atom":
        return atom(node[1])
    if kind == "not":
        return f"(not {to_rasm(node[1], atom)})"
    if kind in ("and", "or", "implies"):
        op = "->" if kind == "implies" else kind
        return f"({to_rasm(node[1], atom)} {op} {to_rasm(node[2], atom)})"
    b = "" if node[1] is None else f"[{node[1][0]}, {node[1][1]}]"
    if kind in ("since", "until"):
        return f"({to_rasm(node[2], atom)} {kind}{b} {to_rasm(node[3], atom)})"
    return f"({kind}{b} {to_rasm(node[2], atom)})"


def to_reelay(node) -> str:
    kind = node[0]
    if kind == "atom":
        return "{" + node[1] + "}"
    if kind == "not":
        return f"(not {to_reelay(node[1])})"
    if kind in ("and", "or", "implies"):
        op = "->" if kind == "implies" else kind
        return f"({to_reelay(node[1])} {op} {to_reelay(node[2])})"
    b = "" if node[1] is None else f"[{node[1][0]}:{node[1][1]}]"
    if kind == "since":
        return f"({to_reelay(node[2])} since{b} {to_reelay(node[3])})"
    return f"({kind}{b} {to_reelay(node[2])})"


def to_rtamt(node) -> str:
    kind = node[0]
    if kind == "atom":
        return f"({node[1]} >= 0.5)"
    if kind == "not":
        return f"(not {to_rtamt(node[1])})"
    if kind == "implies":  # rtamt 0.4.10's pastify() mishandles ->
        return f"((not {to_rtamt(node[1])}) or {to_rtamt(node[2])})"
    if kind in ("and", "or"):
        return f"({to_rtamt(node[1])} {kind} {to_rtamt(node[2])})"
    b = f"[{node[1][0]}:{node[1][1]}]"
    if kind == "until":
        return f"({to_rtamt(node[2])} until{b} {to_rtamt(node[3])})"
    return f"({kind}{b} {to_rtamt(node[2])})"


bits = st.lists(st.tuples(st.booleans(), st.booleans(), st.booleans()), min_size=1, max_size=30)


def rasm_values(formula: str, rows) -> list:
    monitor = compile_properties(HEADER + f"property x: {formula}\n")
    records = [(k, dict(zip(PROPS, row, strict=True))) for k, row in enumerate(rows)]
    (run,) = monitor.run(records)
    assert run.start == 0
    return run.values


@pytest.mark.slow
@settings(max_examples=100, deadline=None)  # building a reelay monitor takes ~50 ms
@given(tree(3, future=False), bits)
def test_past_formulas_agree_with_reelay(node, rows):
    mine = rasm_values(to_rasm(node), rows)
    monitor = reelay.discrete_timed_monitor(pattern=to_reelay(node), condense=False)
    theirs = [monitor.update(dict(zip(PROPS, row, strict=True)))["value"] for row in rows]
    assert mine == theirs, (to_rasm(node), to_reelay(node))


@settings(max_examples=120, deadline=None)
@given(tree(3, future=True), bits.filter(lambda rows: len(rows) > 1))  # rtamt needs two
def test_bounded_future_formulas_agree_with_rtamt(node, rows):
    mine = rasm_values(to_rasm(node), rows)
    spec = rtamt.StlDiscreteTimeSpecification()
    for name in PROPS:
        spec.declare_var(name, "float")
    spec.spec = to_rtamt(node)
    spec.parse()
    data = {"time": list(range(len(rows)))}
    for k, name in enumerate(PROPS):
        data[name] = [1.0 if row[k] else 0.0 for row in rows]
    theirs = [robustness >= 0 for _, robustness in spec.evaluate(data)]
    decided = [k for k, v in enumerate(mine) if v is not None]
    assert [mine[k] for k in decided] == [theirs[k] for k in decided], to_rasm(node)


@pytest.mark.parametrize("name", sorted(timescales.PATTERNS))
@pytest.mark.parametrize("low,high", [(1, 2), (3, 10), (5, 40)])
@pytest.mark.parametrize("body", [True, False])
def test_timescales_patterns_agree_with_reelay(name, low, high, body):
    pattern = timescales.pattern(name, low, high, body=body)
    trace = timescales.trace(1500, seed=low * 100 + high)
    monitor = compile_properties(timescales.RASM_HEADER + f"property x: {pattern.rasm}\n")
    (run,) = monitor.run([(r["time"], {k: v for k, v in r.items() if k != "time"})
                          for r in trace])
    peer = reelay.discrete_timed_monitor(pattern=pattern.reelay, condense=False)
    theirs = [peer.update({k: v for k, v in r.items() if k != "time"})["value"] for r in trace]
    assert run.values == theirs
    if body:  # the generator keeps the pattern's scopes busy: both verdicts occur
        assert True in run.values and False in run.values or name.startswith("Recur")


@pytest.mark.parametrize("name", sorted(timescales.PATTERNS))
def test_timescales_rtamt_forms_agree(name):
    # the rtamt spelling (no open bounds) means the same as rasm's on a shared trace
    pattern = timescales.pattern(name, 2, 6, body=True)
    trace = timescales.trace(200, seed=7)
    monitor = compile_properties(timescales.RASM_HEADER + f"property x: {pattern.rasm}\n")
    (run,) = monitor.run([(r["time"], {k: v for k, v in r.items() if k != "time"})
                          for r in trace])
    spec = rtamt.StlDiscreteTimeSpecification()
    for var in ("p", "q", "r", "sx"):
        spec.declare_var(var, "float")
    spec.spec = pattern.rtamt
    spec.parse()
    data = {"time": [r["time"] for r in trace]}
    for var in ("p", "q", "r", "sx"):
        data[var] = [1.0 if r[var[0]] else 0.0 for r in trace]
    assert run.values == [rob >= 0 for _, rob in spec.evaluate(data)]
