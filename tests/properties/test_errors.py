"""Every bad input is a SourceError at the right file, line and column, with the text marked."""

from __future__ import annotations

import pytest

from rasm.errors import SourceError
from rasm.properties import compile_properties, load_specification

CASES = [
    # (text, line, col, words in the message)
    ("property p: x >", 1, 16, "unexpected end of input"),
    ("property p: x >> 2", 1, 16, "unexpected '>'"),
    ("property p:\n  once[5, 2] x", 2, 7, "upper bound is smaller"),
    # bounds as the decimals written, not 5e+06
    ("property p: once[5000000, 0.000001] x", 1, 17, "empty window [5000000, 0.000001]"),
    ("property p: eventually[1000000, inf] x", 1, 23, "(eventually[1000000, inf])"),
    ("property p: once[-1, 2] x", 1, 18, "cannot be negative"),
    ("property p: eventually[0, inf] x", 1, 23, "infinite bound"),
    ("property p: always[1, inf] x", 1, 19, "infinite bound"),
    ("property p: x until[0, inf] y", 1, 20, "infinite bound"),
    ("property p: eventually x", 1, 13, "needs a bound"),
    ("property p: x until y", 1, 13, "needs a bound"),
    ("property p: once[inf, inf] x", 1, 17, "lower bound"),
    ("property p: once[0, 2h] x", 1, 22, "unknown time unit 'h'"),
    ("property p: x and x > 1", 1, 19, "used as a number here but is a boolean"),
    ("input x: float\nproperty p: x and y", 2, 13, "used as a boolean here but is a number"),
    ("property p: foo(x) > 1", 1, 13, "unknown function 'foo'"),
    ('property p: mode == "a" and mode > 1', 1, 29, "used as a number here but is a string"),
    ('input m: str\nproperty p: m == 3', 2, 13, "cannot compare a string with a number"),
    ('property p: "a" + 1 > 0', 1, 13, "needs a number, not a string"),
    ("property p: (true * 2) > 1", 1, 14, "needs a number, not a boolean"),
    ("property p: x + 1", 1, 13, "a number, but a boolean is needed"),
    ("property p: once (always x)", 1, 19, "unbounded 'always'"),
    ("let a = always x\nproperty p: a", 1, 9, "unbounded 'always'"),
    ("input x: integer\nproperty p: x > 1", 1, 10, "unknown type 'integer'"),
    ("input x: int = 2.5\nproperty p: x > 1", 1, 16, "not of type int"),
    ("input x: float\ninput x: int\nproperty p: x > 1", 2, 1, "already defined"),
    ("property p: x\nproperty p: y", 2, 10, "already defined"),
    ("property p: a\nlet a = x > 1", 2, 5, "already used as a signal"),
    ("input x: float", 1, 1, "no property"),
    ("property p: abs(x, y) > 1", 1, 13, "abs takes 1 argument"),
    ("property p: prev(x, y) > 1", 1, 13, "prev takes one argument"),
    ("property p: x > 1 @", 1, 19, "unexpected character '@'"),
    ("property : x", 1, 10, "unexpected ':'"),
    ("property p: " + " and ".join(f"x > {i}" for i in range(200)), 1, 10, "201 levels deep"),
    ("let a = " + "not " * 200 + "x\nproperty p: a", 1, 5, "let 'a' is nested 201 levels"),
    ("input x: float\nproperty p: " + "not " * 3000 + "x > 1", 2, 1, "nested too deeply"),
    ("input x: float\nproperty p: " + " -> ".join(["x > 1"] * 3000), 2, 1, "nested too deeply"),
    ("let a = a\nproperty p: a", 1, 9, "let 'a' refers to itself"),
    ("input x: float\nlet a = x > 1 and prev(a)\nproperty p: a", 2, 24, "refers to itself"),
    ("input x: float\nproperty p: x < 1e999", 2, 17, "number 1e999 is too large"),
    ("input x: float\nproperty p: x < -1e999", 2, 18, "number 1e999 is too large"),
    ("input x: float\nproperty p: x + 1" + "0" * 400 + " > 1", 2, 17, "is too large"),
    ("input x: float = 1e400\nproperty p: x > 1", 1, 18, "number 1e400 is too large"),
    ("input x: int = -1" + "0" * 400 + "\nproperty p: x > 1", 1, 17, "is too large"),
    ("property p: once[0, 1" + "0" * 400 + "] x", 1, 21, "is too large"),
]


@pytest.mark.parametrize("text,line,col,words", CASES)
def test_error_is_located(text, line, col, words):
    with pytest.raises(SourceError) as info:
        load_specification(text, source="props.rv")
    error = info.value
    assert words in error.message
    assert (error.location.file, error.location.line, error.location.col) == ("props.rv", line, col)
    assert str(error).startswith(f"props.rv:{line}:{col}: ")
    # the offending text is shown with a marker under it
    assert error.excerpt is not None and "^" in error.excerpt
    marked = error.excerpt.splitlines()
    shown = marked[0].strip()
    # a long line is cut around the column, "..." where it was cut
    assert shown.removeprefix("...").removesuffix("...") in text.splitlines()[line - 1]
    assert shown == text.splitlines()[line - 1].strip() or len(shown) <= 106
    assert marked[1].index("^") == 4 + col - 1


def test_compile_raises_the_same_errors():
    with pytest.raises(SourceError, match="needs a bound"):
        compile_properties("property p: eventually x", source="f.rv")


def test_nested_unbounded_always_inside_property_is_rejected_but_outermost_is_fine():
    load_specification("property p: always (x -> once y)")
    with pytest.raises(SourceError, match="outermost"):
        load_specification("property p: always always x")


def test_cli_check_with_a_too_large_number_exits_2(tmp_path, capsys):
    from rasm.cli import main

    props = tmp_path / "big.rv"
    props.write_text("input x: float\nproperty p:\n    always (x < 1e999)\n")
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"time": 0, "x": 1}\n')
    assert main(["check", str(props), str(trace)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rasm: {props}:3:17: number 1e999 is too large")
    assert "Traceback" not in err


def test_the_deepest_formula_allowed_compiles_and_runs():
    text = "input x: float\nproperty p: " + " and ".join(f"x > {i}" for i in range(149))
    monitor = compile_properties(text, source="deep.rv")
    assert [v.value for v in monitor.step(0, {"x": 200})] == [True]
    assert [v.value for v in monitor.step(1, {"x": 100})] == [False]


def test_compile_of_something_other_than_text_says_what_to_pass(tmp_path):
    # these reached the lexer and failed there ("Cannot lex", "'NoneType' object has no
    # attribute 'char_pos'")
    path = tmp_path / "p.rv"
    with pytest.raises(TypeError) as caught:
        compile_properties(path)
    assert str(caught.value) == (
        "a property specification is the text of a .rv file, not PosixPath "
        f"(for a file: compile_properties(Path({str(path)!r}).read_text(), source={str(path)!r}))"
    )
    with pytest.raises(TypeError, match=r"not bytes \(decode it first: text\.decode\('utf-8'\)\)$"):
        compile_properties(b"property p: always true")
    with pytest.raises(
        TypeError, match=r"^a property specification is the text of a \.rv file, not NoneType$"
    ):
        load_specification(None)
