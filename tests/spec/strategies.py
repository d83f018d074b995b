"""Hypothesis strategies: random formulas (as text) and random timed traces."""

from __future__ import annotations

from hypothesis import strategies as st

HEADER = """
event p
event q
input r: bool
input x: float
input y: int
"""

LOWS = [0, 0.5, 1, 2]
WIDTHS = [0, 0.5, 1, 3]


@st.composite
def bounds(draw, past: bool) -> str:
    low = draw(st.sampled_from(LOWS))
    if past and draw(st.integers(0, 4)) == 0:
        return f"[{low}, inf]"
    high = low + draw(st.sampled_from(WIDTHS))
    return f"[{low}, {high}]"


def numeric_atoms(draw) -> str:
    c = draw(st.sampled_from(["0", "0.5", "1", "2"]))
    op = draw(st.sampled_from([">", "<=", "==", "!=", "<", ">="]))
    choice = draw(st.integers(0, 9))
    if choice == 0:
        return f"x {op} {c}"
    if choice == 1:
        return f"prev(x) {op} {c}"
    if choice == 2:
        return f"y {op} {draw(st.sampled_from(['0', '1', '2']))}"
    if choice == 3:
        return f"time >= {draw(st.sampled_from(['1', '2.5', '4']))}"
    if choice == 4:
        return f"x / y {op} {c}"
    if choice == 5:
        k = draw(st.integers(0, 3))
        return f"count{draw(bounds(True))}({draw(formulas(1, future=False))}) >= {k}"
    if choice == 6:
        agg = draw(st.sampled_from(["sum", "avg", "min", "max"]))
        return f"{agg}{draw(bounds(True))}(x) {op} {c}"
    if choice == 7:
        return f"abs(x - y) {op} {c}"
    if choice == 8:
        return f"max(x, y) + min(x, 1) {op} {c}"
    return f"x * 2 - y {op} {c}"


@st.composite
def formulas(draw, depth: int = 3, future: bool = True) -> str:
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        kind = draw(st.integers(0, 6 if future else 5))
        if kind == 6:
            # past and pointwise operators above a future one: values that come late
            inner = f"eventually{draw(bounds(False))} {draw(st.sampled_from(['p', 'q']))}"
            k = draw(st.integers(0, 2))
            return draw(st.sampled_from([
                f"count{draw(bounds(True))}({inner}) >= {k}",
                f"prev({inner})",
                "not prev(always[0, 1] r)",
                f"max[0, 2](x + count[0, 1]({inner})) > 1",
            ]))
        if kind == 0:
            return draw(st.sampled_from(["p", "q", "r", "true", "false", "prev(p)"]))
        if kind <= 2:
            return draw(st.sampled_from(["p", "q", "r"]))
        return numeric_atoms(draw)
    sub = formulas(depth - 1, future)
    ops = ["not", "once", "historically", "and", "or", "->", "since"]
    if future:
        ops += ["eventually", "always", "until"]
    op = draw(st.sampled_from(ops))
    if op == "not":
        return f"not ({draw(sub)})"
    if op in ("once", "historically"):
        bound = draw(st.one_of(st.just(""), bounds(True)))
        return f"{op}{bound} ({draw(sub)})"
    if op in ("eventually", "always"):
        return f"{op}{draw(bounds(False))} ({draw(sub)})"
    if op in ("and", "or", "->"):
        return f"({draw(sub)}) {op} ({draw(sub)})"
    if op == "since":
        bound = draw(st.one_of(st.just(""), bounds(True)))
        return f"({draw(sub)}) since{bound} ({draw(sub)})"
    return f"({draw(sub)}) until{draw(bounds(False))} ({draw(sub)})"


@st.composite
def traces(draw, max_size: int = 25):
    n = draw(st.integers(1, max_size))
    t = draw(st.sampled_from([0, 0.5, 3]))
    records = []
    for _ in range(n):
        rec = {}
        for name in ("p", "q", "r"):
            if draw(st.integers(0, 2)) > 0:
                rec[name] = draw(st.booleans())
        if draw(st.integers(0, 2)) > 0:
            rec["x"] = draw(st.sampled_from([-1.0, 0, 0.5, 1.5, 2.25, 0.1]))
        if draw(st.integers(0, 2)) > 0:
            rec["y"] = draw(st.sampled_from([0, 1, 2]))
        records.append((t, rec))
        t = t + draw(st.sampled_from([0, 0.5, 1, 1, 1.5]))
    return records
