"""The non-temporal sub-language shared with the legitimacy rules."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import SourceError, SpecError
from rasm.properties import (
    Binary,
    Call,
    Literal,
    Name,
    Not,
    Unary,
    compile_expression,
    evaluate,
    infer_types,
    parse_expression,
)
from rasm.properties.printer import unparse


def test_tree_shape_and_precedence():
    e = parse_expression("not a and b or c -> d")
    assert e == Binary(
        "->",
        Binary("or", Binary("and", Not(Name("a")), Name("b")), Name("c")),
        Name("d"),
    )
    assert parse_expression("1 + 2 * x - 3") == Binary(
        "-", Binary("+", Literal(1), Binary("*", Literal(2), Name("x"))), Literal(3)
    )
    assert parse_expression("a -> b -> c") == Binary("->", Name("a"), Binary("->", Name("b"),
                                                                                 Name("c")))
    assert parse_expression("-x") == Unary("-", Name("x"))
    assert parse_expression("-2.5") == Literal(-2.5)
    assert parse_expression("max(x, 1) >= abs(y)") == Binary(
        ">=", Call("max", (Name("x"), Literal(1))), Call("abs", (Name("y"),))
    )
    assert parse_expression('mode == "dock"') == Binary("==", Name("mode"), Literal("dock"))
    assert parse_expression("true != false") == Binary("!=", Literal(True), Literal(False))


def test_locations_point_into_the_users_file():
    # an expression embedded in a YAML file at line 7, column 14
    e = parse_expression("velocity <= 0.1 and\n  stops > 2", source="rules.yaml", line=7, col=14)
    assert str(e.location) == "rules.yaml:7:14"
    assert str(e.left.location) == "rules.yaml:7:14"
    assert str(e.right.location) == "rules.yaml:8:3"  # second line: columns are the file's own
    assert str(e.left.right.location) == "rules.yaml:7:26"


@pytest.mark.parametrize(
    "text,col",
    [("once x", 14), ("x and eventually[0, 1] y", 20), ("prev(x) > 1", 14), ("time > 3", 14),
     ("a since b", 14), ("count[0, 2](a) > 1", 14), ("sum(x) > 1", 14)],
)
def test_temporal_operators_are_refused(text, col):
    with pytest.raises(SourceError, match="temporal operator not allowed here") as info:
        parse_expression(text, source="rules.yaml", line=3, col=14)
    assert (info.value.location.line, info.value.location.col) == (3, col)


def test_syntax_error_location_is_shifted():
    with pytest.raises(SourceError) as info:
        parse_expression("x <= ", source="rules.yaml", line=5, col=20)
    assert str(info.value).startswith("rules.yaml:5:24: unexpected end of input")


def test_types():
    typing = infer_types(parse_expression('v / n <= 0.1 and m == "dock" and ok'), {"n": "int"})
    assert typing.type == "bool"
    assert typing.signals == {"v": "float", "n": "int", "m": "str", "ok": "bool"}
    assert infer_types(parse_expression("n + 1"), {"n": "int"}).type == "int"
    assert infer_types(parse_expression("n / 2"), {"n": "int"}).type == "float"
    assert infer_types(parse_expression("a == b"), {}).signals == {"a": "any", "b": "any"}


@pytest.mark.parametrize(
    "text,declared,message",
    [
        ("x and x > 1", {}, "signal 'x' is used as a number here but is a boolean"),
        ("x > 1", {"x": "bool"}, "signal 'x' is used as a number here but is a boolean"),
        ("frob(x)", {}, "unknown function 'frob'"),
        ('m == 1', {"m": "str"}, "cannot compare a string with a number"),
        ('m + 1 > 0', {"m": "str"}, "signal 'm' is used as a number here but is a string"),
        ('"m" + 1 > 0', {}, "needs a number, not a string"),
        ("b * 2 > 0", {"b": "bool"}, "signal 'b' is used as a number here but is a boolean"),
        ("(1 < 2) * 2 > 0", {}, "needs a number, not a boolean"),
        ("min(1) > 0", {}, "temporal operator not allowed"),
    ],
)
def test_type_errors(text, declared, message):
    with pytest.raises(SourceError, match=message):
        infer_types(parse_expression(text), declared)


def test_division_by_zero_is_undefined_and_comparisons_on_it_are_false():
    env = {"v": 1.0, "n": 0}
    for text in ("v / n > 0", "v / n <= 0", "v / n == v / n", "v / n != 1", "v / n + 1 < 9"):
        e = parse_expression(text)
        assert evaluate(e, env) is False
        assert compile_expression(e)(env) is False
    assert math.isnan(evaluate(parse_expression("v / n"), env))
    assert evaluate(parse_expression("not (v / n > 0)"), env) is True


def test_missing_and_badly_typed_values_raise_spec_error():
    with pytest.raises(SpecError, match="no value for 'y'"):
        evaluate(parse_expression("y > 1"), {})
    with pytest.raises(SpecError, match="no value for 'y'"):
        compile_expression(parse_expression("y > 1"))({})
    with pytest.raises(SpecError, match="cannot evaluate"):
        compile_expression(parse_expression("y > 1"))({"y": "text"})


# ----------------------------------------------------------------- property-based
names = st.sampled_from(["a", "b", "c"])
numbers = st.one_of(st.integers(-5, 5), st.sampled_from([0.5, -1.25, 2.0, 0.1]))


@st.composite
def numeric(draw, depth=2):
    if depth == 0 or draw(st.booleans()):
        return draw(st.one_of(names, numbers.map(str)))
    op = draw(st.sampled_from(["+", "-", "*", "/", "abs", "min", "max", "neg"]))
    x, y = draw(numeric(depth - 1)), draw(numeric(depth - 1))
    if op == "abs":
        return f"abs({x})"
    if op in ("min", "max"):
        return f"{op}({x}, {y})"
    if op == "neg":
        return f"-({x})"
    return f"({x} {op} {y})"


@st.composite
def boolean(draw, depth=2):
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        op = draw(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]))
        return f"{draw(numeric())} {op} {draw(numeric())}"
    op = draw(st.sampled_from(["and", "or", "->", "not"]))
    if op == "not":
        return f"not ({draw(boolean(depth - 1))})"
    return f"({draw(boolean(depth - 1))}) {op} ({draw(boolean(depth - 1))})"


envs = st.fixed_dictionaries({n: numbers for n in ("a", "b", "c")})


@settings(max_examples=100, deadline=None)
@given(boolean(), envs)
def test_compiled_and_direct_evaluation_agree(text, env):
    e = parse_expression(text)
    assert infer_types(e, {}).type == "bool"
    direct = evaluate(e, env)
    assert direct in (True, False)
    assert compile_expression(e)(env) is direct


@settings(max_examples=100, deadline=None)
@given(boolean())
def test_printing_and_parsing_round_trip(text):
    e = parse_expression(text)
    assert parse_expression(unparse(e)) == e
