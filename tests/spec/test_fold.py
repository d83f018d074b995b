"""rasm.spec.fold: a folded program does what the program did, on random programs.

The programs mix the constructs generated monitors use (assignments, ``if``/``else``,
``while`` loops, ``and``/``or``/``not``, identity and equality tests, the UNSET sentinel) over
known names, other names, and tracked locals (whose dead assignments fold may drop). The
straightforward version is the unfolded program: both run from the same start, and everything
but the tracked locals must end the same, the log of evaluated values included.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.spec.fold import fold

KNOWN = ("e0", "e1")
OTHER = ("a", "b")
TRACKED = ("v1", "_last0", "v2")
LOGGED = TRACKED[:2]  # v2 is read less: its assignments are often dead
TRACKED_PATTERN = r"v\d+|_last\d+"
VALUES = [True, False, None, 0, 1, "s"]
KNOWN_VALUES = [True, False, None]  # generated code knows events (False); literals for "is"
UNSET = type("Unset", (), {})()


def expressions(depth: int = 3) -> st.SearchStrategy[str]:
    leaf = st.sampled_from([*KNOWN, *OTHER, *TRACKED, "True", "False", "None", "UNSET"])
    if depth == 0:
        return leaf
    sub = expressions(depth - 1)
    return st.one_of(
        leaf,
        sub.map(lambda e: f"(not {e})"),
        st.tuples(sub, st.sampled_from(["and", "or", "is", "is not", "==", "!="]), sub).map(
            lambda t: f"({t[0]} {t[1]} {t[2]})"
        ),
        st.tuples(sub, sub, sub).map(lambda t: f"({t[0]} if {t[1]} else {t[2]})"),
    )


def _indent(lines: list[str]) -> list[str]:
    return ["    " + line for line in lines] or ["    pass"]


@st.composite
def statements(draw, depth: int = 2) -> list[str]:
    out: list[str] = []
    # weighted towards what fold follows: known values assigned, read after branches and loops
    simple = ["assign", "note", "known", "known", "log", "read", "read"]
    kinds = simple + ["if", "if", "if-else", "queue", "while"] if depth else simple
    for _ in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(kinds))
        e = draw(st.integers(0, 3).flatmap(expressions))
        tracked = draw(st.sampled_from(TRACKED))
        if kind == "assign":
            out.append(f"{draw(st.sampled_from([*OTHER, *TRACKED]))} = {e}")
        elif kind == "note":  # a value with an effect, kept even when nobody reads it
            out.append(f"{tracked} = note({e})")
        elif kind == "known":  # a value fold can follow
            out.append(f"{tracked} = {draw(st.sampled_from(['True', 'False', 'None', 'UNSET']))}")
        elif kind == "log":
            out.append(f"log.append({e})")
        elif kind == "read":
            out.append(f"log.append({draw(st.sampled_from(LOGGED))})")
        elif kind.startswith("if"):
            out.append(f"if {e}:")
            out += _indent(draw(statements(depth - 1)))
            if kind == "if-else":
                out.append("else:")
                out += _indent(draw(statements(depth - 1)))
        elif kind == "queue":  # a loop over a queue, like a generated window's
            out.append(f"while q and {e}:")
            out += _indent(["log.append(q.pop())", *draw(statements(depth - 1))])
        else:
            out.append(f"while {e}:")  # a false test never runs it; otherwise break at once
            out += _indent([*draw(statements(depth - 1)), "break"])
        if kind in ("if", "if-else", "queue", "while"):  # what is known after it?
            out += [f"log.append({name})" for name in LOGGED]
    return out


def run(source: str, start: dict) -> dict:
    log: list = []
    space = {"UNSET": UNSET, "log": log, "q": [1, 2, 3], "note": lambda x: log.append(x), **start}
    try:
        exec(source, space)
    except Exception as exc:  # the same failure is part of doing the same
        space["raised"] = type(exc)
    return {k: v for k, v in space.items() if k not in (*TRACKED, "note", "__builtins__")}


@settings(max_examples=300, deadline=None)
@given(
    statements(),
    st.fixed_dictionaries(
        {
            **{name: st.sampled_from(KNOWN_VALUES) for name in KNOWN},
            **{name: st.sampled_from(VALUES) for name in OTHER},
        }
    ),
    st.fixed_dictionaries({name: st.sampled_from([*VALUES, UNSET]) for name in TRACKED}),
)
def test_a_folded_program_does_what_the_program_did(lines, start, locals_):
    source = "\n".join(lines) + "\n"
    known = tuple((name, start[name]) for name in KNOWN)
    folded = fold(source, known, TRACKED_PATTERN)
    assert run(folded, {**start, **locals_}) == run(source, {**start, **locals_})


def test_what_folds_away():
    source = (
        "_last0 = UNSET\n"
        "if not e0:\n"
        "    _last0 = True\n"
        "v1 = s is not None\n"  # read by nobody: dropped
        "if e0 and x:\n"
        "    log.append(1)\n"
        "while e0 and w:\n"
        "    w.pop()\n"
        "if _last0 is not UNSET:\n"
        "    latest['p'] = _last0\n"
    )
    assert fold(source, (("e0", False),), TRACKED_PATTERN) == "latest['p'] = True\n"


def test_dead_assignments_go_and_take_only_their_own_reads_with_them():
    known = (("e0", False),)
    # v2 is read by nobody, v1 by v2 and by the log: v2 goes, v1 stays
    source = "v1 = a\nv2 = v1\nlog.append(v1)\n"
    assert fold(source, known, TRACKED_PATTERN) == "v1 = a\nlog.append(v1)\n"
    # v1 read by v2 only: both go; a value with an effect stays
    source = "v1 = a\nv2 = v1 is not None\n_last0 = note(b)\n"
    assert fold(source, known, TRACKED_PATTERN) == "_last0 = note(b)\n"


def test_a_known_name_must_not_be_assigned():
    with pytest.raises(ValueError, match="e0 is assigned"):
        fold("if a:\n    e0 = 1\n", (("e0", False),), TRACKED_PATTERN)


def test_what_fold_does_not_know_is_refused():
    with pytest.raises(TypeError, match="cannot fold"):
        fold("x = [e0 for e0 in y]\n", (("e0", False),), TRACKED_PATTERN)
    with pytest.raises(TypeError, match="cannot fold"):
        fold("try:\n    x = 1\nexcept E:\n    pass\n", (("e0", False),), TRACKED_PATTERN)
