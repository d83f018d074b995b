"""The compiler's middle: every pass handles every node class, the tree's structure is generic,
and the generated code reads exactly the runtime names the monitor provides."""

from __future__ import annotations

import builtins
import dis
import importlib
import pkgutil
from pathlib import Path
from types import CodeType

import pytest
from hypothesis import given, settings

import rasm
from rasm.properties import ast
from rasm.properties.ast import NODES, children, rebuild, walk
from rasm.properties.codegen import RUNTIME, Runtime, generate
from rasm.properties.loader import load_specification
from rasm.properties.monitor import Monitor
from rasm.properties.visitor import Transformer, Visitor, method_name

from .strategies import HEADER, formulas

# -------------------------------------------------------------------------- every pass


def _passes() -> list[type[Visitor]]:
    """Every pass in rasm: the subclasses of Visitor in the modules that import it."""
    root = Path(rasm.__file__).parent
    for module in pkgutil.walk_packages([str(root)], "rasm."):
        path = root.joinpath(*module.name.split(".")[1:])
        source = path / "__init__.py" if module.ispkg else path.with_suffix(".py")
        if "rasm.properties.visitor" in source.read_text(encoding="utf-8"):
            importlib.import_module(module.name)
    found, todo = [], list(Visitor.__subclasses__())
    while todo:
        cls = todo.pop()
        todo += cls.__subclasses__()
        if cls.__module__.startswith("rasm.") and cls is not Transformer:
            found.append(cls)
    return sorted(set(found), key=lambda cls: f"{cls.__module__}.{cls.__qualname__}")


PASSES = _passes()


def test_the_passes_are_found():
    names = {cls.__qualname__ for cls in PASSES}
    # one of each kind, in the modules the compiler's middle spans
    assert {"TypeScope", "_Printer", "FormulaGenerator", "_Explainer", "_Reach", "_After",
            "_Bounded", "_Normalise", "_IsTime", "_LooksAhead", "_Show", "_Windows",
            "_Evaluate", "_Source", "_Checker", "_Condition", "_Value"} <= names


@pytest.mark.parametrize("cls", PASSES, ids=lambda cls: f"{cls.__module__}.{cls.__qualname__}")
def test_every_pass_handles_every_node_class(cls):
    missing = [node.__name__ for node in NODES if not callable(getattr(cls, method_name(node),
                                                                       None))]
    assert not missing, f"{cls.__qualname__} has no method for {missing}"
    assert set(cls._methods) == set(NODES)


def test_a_node_class_without_a_method_is_named():
    class Partial(Visitor[str]):
        def literal(self, node):
            return "literal"

    assert Partial().visit(ast.Literal(1)) == "literal"
    with pytest.raises(TypeError, match="Partial has no method for Name nodes"):
        Partial().visit(ast.Name("x"))


def test_method_names_follow_the_classes():
    assert [method_name(node) for node in NODES] == [
        "literal", "name", "unary", "not_", "binary", "call",
        "time", "prev", "past", "future", "since", "until", "aggregate",
    ]


# -------------------------------------------------------------------------- structure


@settings(max_examples=200, deadline=None)
@given(formulas(4))
def test_children_rebuild_and_walk_agree_on_every_node(text):
    formula = load_specification(HEADER + f"property f: {text}\n").properties[0].formula
    nodes = list(walk(formula))
    # walk: parents before children, left to right, every node once
    def preorder(node):
        yield node
        for child in children(node):
            yield from preorder(child)

    assert [id(n) for n in nodes] == [id(n) for n in preorder(formula)]
    for node in nodes:
        assert rebuild(node, children(node)) == node
        fresh = [ast.Literal(k) for k in range(len(children(node)))]
        assert children(rebuild(node, fresh)) == tuple(fresh)


# -------------------------------------------------------------------------- runtime names

# every node class, every operator and function, every kind of signal, window shape and
# future operator placement (inline, on streams, deciding early at the root)
CORPUS = HEADER + """
input s: str = "idle"
input u: float
input w: int = 2
property literal_name: p and true
property unary_call: -x < abs(x) and min(x, y) <= max(x, 1)
property arithmetic: x + y - 1 * 2 / 3 > 0 or x == 1 or y != 2 or x >= 0
property equal_any: z == v
property time_prev: time - prev(time) >= 0.2 and prev(x) != x
property past: once p and once[1, 2] q and historically r and historically[0, 1] p
property since: p since q and (p since[1, 2] q)
property aggregates: count(p) + count[0, 1](q) + count[1, 2](r) > 0 and sum[0, 1](x) < 2 \
and avg(x) > 0 and min[0, 1](x) < max[0, 2](x)
property future: p -> eventually[0, 1] q
property always: always[0, 1] r
property until: p until[0, 2] q
property late_window: once[0, 1](eventually[0, 1] p) and count[0, 1](eventually[0, 1] q) > 0
property late_pointwise: not (eventually[0, 1] p) or -(count[0, 1](eventually[0, 1] q)) < 0
property late_join: (eventually[0, 1] p) and (eventually[0, 2] q) or \
abs(count[0, 1](eventually[0, 1] p)) + min(x, count[0, 1](eventually[0, 1] q)) > 1
property late_past: prev(eventually[0, 1] p) and (p since (eventually[0, 1] q)) \
and (eventually[0, 1] p) until[0, 1] q and max[0, 1](count[0, 1](eventually[0, 1] r)) > 0
property strings: s == "dock" or u > w
"""


def _globals(code: CodeType) -> set[str]:
    """The global names a code object and the functions inside it read or write."""
    names = {ins.argval for ins in dis.get_instructions(code)
             if ins.opname in ("LOAD_GLOBAL", "LOAD_NAME", "STORE_GLOBAL", "DELETE_GLOBAL")}
    for const in code.co_consts:
        if isinstance(const, CodeType):
            names |= _globals(const)
    return names


def test_the_corpus_covers_every_operator():
    spec = load_specification(CORPUS)
    nodes = [n for p in spec.properties for n in walk(p.formula)]
    assert {type(n) for n in nodes} == set(NODES)
    ops = {(type(n).__name__, getattr(n, "op", getattr(n, "func", None))) for n in nodes}
    assert {op for kind, op in ops if kind == "Binary"} == set(
        ast.ARITHMETIC + ast.COMPARISONS + ast.BOOLEAN
    )
    assert {op for kind, op in ops if kind == "Call"} == {"abs", "min", "max"}
    assert {op for kind, op in ops if kind == "Aggregate"} == {"count", "sum", "avg", "min",
                                                               "max"}
    assert {op for kind, op in ops if kind == "Past"} == {"once", "historically"}
    assert {op for kind, op in ops if kind == "Future"} == {"eventually", "always"}
    assert set(spec.signals.values()) == {"float", "int", "bool", "str", "any"}


def test_the_generated_code_reads_exactly_the_runtime_names():
    spec = load_specification(CORPUS)
    beyond: set[str] = set()
    for hook, robustness in ((False, False), (True, False), (False, True)):
        program = generate(spec, hook=hook, robustness=robustness)
        read = _globals(compile(program.source, "<corpus>", "exec")) - {"factory"}
        outside = read - set(program.constants) - set(dir(builtins))
        assert outside <= set(RUNTIME), outside - set(RUNTIME)
        beyond |= outside
    assert beyond == set(RUNTIME)


@settings(max_examples=100, deadline=None)
@given(formulas(4))
def test_no_formula_reads_a_name_nobody_provides(text):
    program = generate(load_specification(HEADER + f"property f: {text}\n"), hook=True)
    read = _globals(compile(program.source, "<formula>", "exec")) - {"factory"}
    assert read - set(program.constants) - set(dir(builtins)) <= set(RUNTIME)


def test_the_monitor_provides_every_runtime_name():
    monitor = Monitor(load_specification(CORPUS))
    # (exec adds the builtins and the factory it defines)
    provided = set(monitor._namespace) - set(monitor.program.constants)
    assert provided - {"__builtins__", "factory"} == set(RUNTIME) == set(Runtime._fields)
