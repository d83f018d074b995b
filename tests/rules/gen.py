"""Hypothesis strategies: rules files over small finite domains, as YAML text."""

from __future__ import annotations

import json

from hypothesis import strategies as st

VARIABLES = """variables:
  x: {type: int, min: 0, max: 3}
  y: {type: int, min: -2, max: 2}
  m: {type: enum, values: [a, b, c]}
  f: {type: bool}
"""

_OPS = st.sampled_from(["<", "<=", ">", ">=", "==", "!="])
_K = st.integers(-2, 4)


def _cmp(term: str):
    return st.builds(lambda op, k: f"{term} {op} {k}", _OPS, _K)


atoms = st.one_of(
    _cmp("x"),
    _cmp("y"),
    _cmp("x + y"),
    _cmp("y * 2 - x"),
    _cmp("abs(y)"),
    _cmp("min(x, y)"),
    _cmp("max(x, y) / 2"),
    _cmp("x / y"),  # y may be 0: undefined, so the comparison is false
    st.builds(lambda op, v: f'm {op} "{v}"', st.sampled_from(["==", "!="]),
              st.sampled_from("abc")),
    st.sampled_from(["f", "not f", "f == (x > 1)", "true", "false"]),
)


def _combine(children):
    return st.one_of(
        st.builds(lambda a, b: f"({a}) and ({b})", children, children),
        st.builds(lambda a, b: f"({a}) or ({b})", children, children),
        st.builds(lambda a, b: f"({a}) -> ({b})", children, children),
        st.builds(lambda a: f"not ({a})", children),
    )


conditions = st.recursive(atoms, _combine, max_leaves=3)


@st.composite
def rules_files(draw, min_rules: int = 1, max_rules: int = 6) -> str:
    """The text of a rules file with 1..6 rules named r0, r1, ..."""
    count = draw(st.integers(min_rules, max_rules))
    lines = [VARIABLES, "rules:"]
    for index in range(count):
        lines.append(f"  - name: r{index}")
        if draw(st.booleans()):
            lines.append(f"    when: {json.dumps(draw(conditions))}")
        lines.append(f"    require: {json.dumps(draw(conditions))}")
    return "\n".join(lines) + "\n"


numeric_atoms = st.one_of(_cmp("x"), _cmp("y"), _cmp("x + y"), _cmp("y * 2 - x"), _cmp("abs(y)"))
guard_atoms = st.one_of(
    st.builds(lambda op, v: f'm {op} "{v}"', st.sampled_from(["==", "!="]),
              st.sampled_from("abc")),
    st.sampled_from(["f", "not f", 'f or m == "a"']),
)
numeric_conditions = st.recursive(numeric_atoms, _combine, max_leaves=2)


@st.composite
def guarded_rules_files(draw, max_rules: int = 7) -> str:
    """Rules guarded by modes and flags (m, f) that no ``require`` reads: the split's domain."""
    count = draw(st.integers(2, max_rules))
    lines = [VARIABLES, "rules:"]
    for index in range(count):
        lines.append(f"  - name: r{index}")
        parts = draw(st.lists(st.one_of(guard_atoms, numeric_atoms), max_size=2))
        if index == 0:  # at least one guard, so that the split applies
            parts.append(draw(guard_atoms))
        if parts:
            lines.append("    when: " + json.dumps(" and ".join(f"({p})" for p in parts)))
        lines.append(f"    require: {json.dumps(draw(numeric_conditions))}")
    return "\n".join(lines) + "\n"


def with_plan_fields(text: str, plan: set[str]) -> str:
    """``text`` (a file of :data:`VARIABLES`) with the variables in ``plan`` marked
    ``plan: true``."""
    lines = []
    for line in text.split("\n"):
        name = line.strip().split(":", 1)[0]
        if line.startswith("  ") and not line.startswith("   ") and name in plan:
            line = line.replace("}", ", plan: true}", 1)
        lines.append(line)
    return "\n".join(lines)


plan_field_sets = st.sets(st.sampled_from(["x", "y", "m", "f"]), min_size=1, max_size=3)


@st.composite
def planned_rules_files(draw, max_rules: int = 6) -> str:
    """:func:`rules_files` with one to three of the variables marked as plan fields."""
    return with_plan_fields(draw(rules_files(max_rules=max_rules)), draw(plan_field_sets))


@st.composite
def planned_guarded_rules_files(draw, max_rules: int = 7) -> str:
    """:func:`guarded_rules_files` with some variables marked as plan fields."""
    return with_plan_fields(draw(guarded_rules_files(max_rules=max_rules)),
                            draw(plan_field_sets))
