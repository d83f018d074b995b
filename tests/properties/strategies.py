"""Hypothesis strategies: random formulas (as text) and random timed traces."""

from __future__ import annotations

from decimal import Decimal

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


# decimal traces: records on a grid of 0.1 s or 0.01 s, bounds on the same grid
UNITS = [Decimal("0.1"), Decimal("0.01")]
OFFSETS = [Decimal("0"), Decimal("0.3"), Decimal("1700000000"), Decimal("1699999999.97")]


@st.composite
def bounds(draw, past: bool, unit: Decimal | None = None) -> str:
    """``[low, high]`` in seconds; with ``unit``, multiples of it (landing on record gaps),
    written in seconds or milliseconds."""
    if unit is not None:
        low = unit * draw(st.integers(0, 5))
        if past and draw(st.integers(0, 6)) == 0:
            return f"[{_seconds(low, draw)}, inf]"
        high = low + unit * draw(st.sampled_from([0, 1, 2, 3, 5]))
        return f"[{_seconds(low, draw)}, {_seconds(high, draw)}]"
    low = draw(st.sampled_from(LOWS))
    if past and draw(st.integers(0, 4)) == 0:
        return f"[{low}, inf]"
    high = low + draw(st.sampled_from(WIDTHS))
    return f"[{low}, {high}]"


def _seconds(value: Decimal, draw) -> str:
    if draw(st.booleans()):
        return f"{(value * 1000).normalize():f}ms"
    return f"{value.normalize():f}"


def numeric_atoms(draw, unit: Decimal | None = None) -> str:
    c = draw(st.sampled_from(["0", "0.5", "1", "2"]))
    op = draw(st.sampled_from([">", "<=", "==", "!=", "<", ">="]))
    choice = draw(st.integers(0, 11))
    if choice >= 10:  # time arithmetic, against gaps on the trace's grid (exact: 0.3 - 0.1)
        return f"{draw(time_terms(1, unit))} {op} {draw(grid_decimals(unit))}"
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
        inner = draw(formulas(1, future=False, unit=unit))
        return f"count{draw(bounds(True, unit))}({inner}) >= {k}"
    if choice == 6:
        agg = draw(st.sampled_from(["sum", "avg", "min", "max"]))
        return f"{agg}{draw(bounds(True, unit))}(x) {op} {c}"
    if choice == 7:
        return f"abs(x - y) {op} {c}"
    if choice == 8:
        return f"max(x, y) + min(x, 1) {op} {c}"
    return f"x * 2 - y {op} {c}"


@st.composite
def decimals(draw, digits: int = 9, limit: int = 10**12) -> str:
    """A decimal number of seconds written with up to ``digits`` decimals."""
    scale = 10 ** (9 - draw(st.integers(0, digits)))
    ns = draw(st.integers(-limit, limit)) // scale * scale
    return f"{Decimal(ns).scaleb(-9).normalize():f}"


@st.composite
def grid_decimals(draw, unit: Decimal | None) -> str:
    """A number on the trace's grid (``unit``, or 0.5 s): a small multiple of it, where gaps
    land, or one of the traces' times."""
    step = unit if unit is not None else Decimal("0.5")
    offset = draw(st.sampled_from([Decimal(0), Decimal(0), *OFFSETS]))
    return f"{(offset + step * draw(st.integers(-3, 8))).normalize():f}"


@st.composite
def time_terms(draw, depth: int = 2, unit: Decimal | None = None) -> str:
    """Arithmetic on ``time``: sums, differences, negation, abs, min and max of times, prev,
    a signal and decimal numbers (on the trace's grid, or any with up to nine decimals)."""
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        return draw(st.one_of(
            st.sampled_from(["time", "prev(time)", "time - prev(time)", "x"]),
            grid_decimals(unit),
            decimals(9, 10**10),
        ))
    sub = time_terms(depth - 1, unit)
    op = draw(st.sampled_from(["+", "-", "neg", "abs", "min", "max", "prev"]))
    if op == "neg":
        return f"-({draw(sub)})"
    if op in ("abs", "prev"):
        return f"{op}({draw(sub)})"
    if op in ("min", "max"):
        return f"{op}({draw(sub)}, {draw(sub)})"
    return f"time {op} ({draw(sub)})" if draw(st.booleans()) else f"({draw(sub)}) {op} time"


@st.composite
def time_comparisons(draw, unit: Decimal | None = None) -> str:
    """A comparison of time arithmetic with time arithmetic or a number: half of them shapes
    that land on the grid's decimals (where binary arithmetic errs), half random terms."""
    op = draw(st.sampled_from([">", "<=", "==", "!=", "<", ">="]))
    g, h = draw(grid_decimals(unit)), draw(grid_decimals(unit))
    if draw(st.booleans()):
        return draw(st.sampled_from([
            f"time - prev(time) {op} {g}",
            f"time - {g} {op} prev(time) + {h}",
            f"abs(time - prev(time) - {g}) {op} {h}",
            f"min(time - prev(time), {g}) {op} {h}",
            f"-(time - prev(time)) {op} -({g})",
            f"time {op} {g}",
            f"time - prev(prev(time)) {op} {g}",
            f"time + x - prev(time) {op} {g}",
            f"max(time, {g}) - {h} {op} prev(time)",
            # a future operator's value in the arithmetic: there times are floats of seconds
            f"time - count[0, 1](eventually[0, 1] p) {op} {g}",
            f"time {op} count[0, 1](eventually[0, 1] p) + {g}",
        ]))
    right = draw(st.one_of(time_terms(2, unit), grid_decimals(unit), decimals(9, 10**10)))
    return f"{draw(time_terms(2, unit))} {op} {right}"


@st.composite
def formulas(draw, depth: int = 3, future: bool = True, unit: Decimal | None = None) -> str:
    """A random formula; with ``unit``, its bounds are multiples of ``unit`` seconds."""
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        kind = draw(st.integers(0, 6 if future else 5))
        if kind == 6:
            # past and pointwise operators above a future one: values that come late
            inner = f"eventually{draw(bounds(False, unit))} {draw(st.sampled_from(['p', 'q']))}"
            k = draw(st.integers(0, 2))
            return draw(st.sampled_from([
                f"count{draw(bounds(True, unit))}({inner}) >= {k}",
                f"prev({inner})",
                "not prev(always[0, 1] r)",
                f"max[0, 2](x + count[0, 1]({inner})) > 1",
            ]))
        if kind == 0:
            return draw(st.sampled_from(["p", "q", "r", "true", "false", "prev(p)"]))
        if kind <= 2:
            return draw(st.sampled_from(["p", "q", "r"]))
        return numeric_atoms(draw, unit)
    sub = formulas(depth - 1, future, unit)
    ops = ["not", "once", "historically", "and", "or", "->", "since"]
    if future:
        ops += ["eventually", "always", "until"]
    return _operator(draw, draw(st.sampled_from(ops)), sub, unit)


def _operator(draw, op: str, sub, unit: Decimal | None) -> str:
    """``op`` applied to operands drawn from ``sub``, with a bound where it takes one."""
    if op == "not":
        return f"not ({draw(sub)})"
    if op in ("once", "historically"):
        bound = draw(st.one_of(st.just(""), bounds(True, unit)))
        return f"{op}{bound} ({draw(sub)})"
    if op in ("eventually", "always"):
        return f"{op}{draw(bounds(False, unit))} ({draw(sub)})"
    if op in ("and", "or", "->"):
        return f"({draw(sub)}) {op} ({draw(sub)})"
    if op == "since":
        bound = draw(st.one_of(st.just(""), bounds(True, unit)))
        return f"({draw(sub)}) since{bound} ({draw(sub)})"
    return f"({draw(sub)}) until{draw(bounds(False, unit))} ({draw(sub)})"


ORDERED_LATE = ["eventually[0, 1] p", "always[0.5, 2] q", "not eventually[0, 0.5] q",
                "eventually[1, 1] (p or q)"]
UNORDERED_LATE = ["p and eventually[0, 2] q", "(eventually[0, 1] p) or (always[0, 1] r)",
                  "prev(eventually[0, 1] q)"]
OTHER_SIDES = ["0", "1", "2", "3", "-1", "2.5", "0.5", "y", "x", "x / y", "prev(y)",
               "count[0, 1](p)"]


@st.composite
def count_comparisons(draw, late: list[str] = ORDERED_LATE) -> str:
    """``count[a,b](φ) op v`` (or ``v op count…``) with φ's values coming late and v known at
    its record: a number, a signal, undefined (``x / y`` at y = 0, ``prev(y)`` at the start)."""
    count = f"count{draw(bounds(True))}({draw(st.sampled_from(late))})"
    op = draw(st.sampled_from(["==", "!=", "<", "<=", ">", ">="]))
    other = draw(st.sampled_from(OTHER_SIDES))
    return f"{count} {op} {other}" if draw(st.booleans()) else f"{other} {op} {count}"


@st.composite
def traces(draw, max_size: int = 25):
    n = draw(st.integers(1, max_size))
    t = draw(st.sampled_from([0, 0.5, 3]))
    records = []
    for _ in range(n):
        records.append((t, _record(draw)))
        t = t + draw(st.sampled_from([0, 0.5, 1, 1, 1.5]))
    return records


@st.composite
def decimal_traces(draw, unit: Decimal, max_size: int = 25, exact: bool = False):
    """Records on a grid of ``unit`` seconds from an offset (0, or epoch-like), with equal
    times and irregular gaps; each time is the float of its decimal (``exact``: the Decimal
    itself)."""
    n = draw(st.integers(1, max_size))
    t = draw(st.sampled_from(OFFSETS))
    records = []
    for _ in range(n):
        rec = _record(draw)
        records.append((t if exact else float(t), rec))
        t += unit * draw(st.sampled_from([0, 1, 1, 1, 2, 3, 7]))
    return records


def _record(draw) -> dict:
    rec = {}
    for name in ("p", "q", "r"):
        if draw(st.integers(0, 2)) > 0:
            rec[name] = draw(st.booleans())
    if draw(st.integers(0, 2)) > 0:
        rec["x"] = draw(st.sampled_from([-1.0, 0, 0.5, 1.5, 2.25, 0.1]))
    if draw(st.integers(0, 2)) > 0:
        rec["y"] = draw(st.sampled_from([0, 1, 2]))
    return rec


@st.composite
def numeric_formulas(draw, depth: int = 3, future: bool = True,
                     unit: Decimal | None = None) -> str:
    """A random formula whose atoms are mostly comparisons of numbers (robustness is then a
    distance, not ±inf), over every operator of :func:`formulas`."""
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        if draw(st.integers(0, 5)) == 0:
            return draw(formulas(0, future, unit))
        c = draw(st.sampled_from(["0", "0.5", "1", "2"]))
        op = draw(st.sampled_from([">", "<=", "==", "!=", "<", ">="]))
        return draw(st.sampled_from([f"x {op} {c}", f"x {op} {c}", f"y {op} {c}",
                                     f"abs(x - y) {op} {c}", f"x - prev(x) {op} {c}"]))
    sub = numeric_formulas(depth - 1, future, unit)
    ops = ["not", "once", "historically", "and", "or", "->", "since"]
    if future:
        ops += ["eventually", "always", "until", "eventually", "always"]
    return _operator(draw, draw(st.sampled_from(ops)), sub, unit)
