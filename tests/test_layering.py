"""The import layering of rasm: no cycles, and every import in the intended direction.

Imports are read with ``ast`` from every module of rasm/. No cycle: neither among the imports
at module level (what runs when a module loads) nor among every import that runs, deferred ones
(inside a function) included; an import for type checkers alone (``if TYPE_CHECKING:``) runs
never and is left out of the cycles. The directions count every import.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

import rasm

ROOT = Path(rasm.__file__).parent


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {_module_name(path): path for path in sorted(ROOT.rglob("*.py"))}


def _imported(module: str, node: ast.Import | ast.ImportFrom) -> set[str]:
    """The modules an import statement names: ``from package import submodule`` names the
    submodule, ``from module import name`` the module."""
    if isinstance(node, ast.Import):
        return {alias.name for alias in node.names}
    if node.level:  # relative: from the module's package, up node.level - 1 packages
        package = module.split(".")
        if MODULES[module].name != "__init__.py":
            package.pop()
        base = ".".join(package[: len(package) - node.level + 1] + [node.module or ""]).strip(".")
    else:
        base = node.module or ""
    names = {f"{base}.{alias.name}" for alias in node.names}
    submodules = names & MODULES.keys()
    return submodules if submodules == names else submodules | {base}


@functools.cache
def imports(module: str, *, module_level_only: bool) -> frozenset[str]:
    """The other modules of rasm (and the third-party ones) ``module`` imports."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    nodes = tree.body if module_level_only else ast.walk(tree)
    found: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import | ast.ImportFrom):
            found |= _imported(module, node)
    return frozenset(found - {module})


def _type_checking_only(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and ast.unparse(node.test) in (
        "TYPE_CHECKING",
        "typing.TYPE_CHECKING",
    )


@functools.cache
def runs(module: str) -> frozenset[str]:
    """The other modules of rasm ``module`` imports when it loads or when a function of it
    runs: every import but those for type checkers alone."""
    found: set[str] = set()
    stack: list[ast.AST] = list(ast.parse(MODULES[module].read_text(encoding="utf-8")).body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _type_checking_only(node):
            stack.extend(node.orelse)  # what runs when not type checking
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            found |= _imported(module, node)
        stack.extend(ast.iter_child_nodes(node))
    return frozenset((found - {module}) & MODULES.keys())


def _assert_no_cycle(graph: dict[str, frozenset[str]]) -> None:
    done: set[str] = set()

    def visit(module: str, path: list[str]) -> None:
        if module in path:
            cycle = " -> ".join([*path[path.index(module) :], module])
            raise AssertionError(f"import cycle: {cycle}")
        if module in done:
            return
        for imported in sorted(graph[module]):
            visit(imported, [*path, module])
        done.add(module)

    for module in graph:
        visit(module, [])


def test_module_level_imports_form_no_cycle() -> None:
    _assert_no_cycle(
        {module: imports(module, module_level_only=True) & MODULES.keys() for module in MODULES}
    )


def test_the_imports_that_run_deferred_ones_included_form_no_cycle() -> None:
    _assert_no_cycle({module: runs(module) for module in MODULES})


def test_the_cycle_check_sees_deferred_imports_and_not_type_checking_ones() -> None:
    """rasm.trace_mcap imports rasm.trace at module level; rasm.ros2.types imports the codec
    inside a method, and the codec's TypeStore import is for type checkers alone."""
    assert "rasm.trace" in runs("rasm.trace_mcap")
    assert "rasm.ros2.codec" in runs("rasm.ros2.types")
    assert "rasm.ros2.types" not in runs("rasm.ros2.codec")
    try:
        _assert_no_cycle({"a": frozenset({"b"}), "b": frozenset({"a"})})
    except AssertionError as exc:
        assert "import cycle: a -> b -> a" in str(exc)
    else:
        raise AssertionError("a cycle went unnoticed")


def _importers(prefix: str) -> set[str]:
    """The modules of rasm importing ``prefix`` or a module under it."""
    return {
        module
        for module in MODULES
        if any(
            name == prefix or name.startswith(f"{prefix}.")
            for name in imports(module, module_level_only=False)
        )
    }


def _under(module: str, *packages: str) -> bool:
    return any(module == p or module.startswith(f"{p}.") for p in packages)


@pytest.mark.parametrize(
    "lower", ["rasm.properties", "rasm.knowledge", "rasm.comm", "rasm.statechart", "rasm.twin"]
)
def test_the_layers_below_the_platform_never_import_it(lower: str) -> None:
    upward = {m for m in _importers("rasm.platform") | _importers("rasm.cli") if _under(m, lower)}
    assert upward == set()


def test_only_the_command_line_draws_on_the_screen() -> None:
    assert {m for m in _importers("rich") if not _under(m, "rasm.cli")} == set()
    assert {m for m in _importers("rasm.cli") if not _under(m, "rasm.cli")} == set()


BLOCKS = {
    "rasm.platform.logging_and_tracking",
    "rasm.platform.state_manager",
    "rasm.platform.knowledge_manager",
    "rasm.platform.storage_manager",
    "rasm.platform.communication_manager",
    "rasm.platform.telegraf",
    "rasm.platform.trustworthiness_manager",
    "rasm.platform.adaptation_manager",
    "rasm.platform.trustworthiness_checker",
    "rasm.platform.adaptation_orchestrator",
    "rasm.platform.core",
    "rasm.platform.fallback",
}


def test_a_building_block_imports_no_other_block_and_only_the_assembly_imports_them() -> None:
    assert BLOCKS <= MODULES.keys()
    for block in BLOCKS:
        assert imports(block, module_level_only=False) & BLOCKS == set(), block
    importers = {m for block in BLOCKS for m in _importers(block)} - BLOCKS
    # the assembly, the package face (names loaded on first use), rasm's own face, and the
    # summary of a run (which reads the loop's counts)
    assert importers <= {
        "rasm.platform.assembly",
        "rasm.platform.summary",
        "rasm.platform",
        "rasm",
    }


# The bus, a shared store and the monitors attached to a live loop sit low: each imports nothing
# built on it.
BUILT_ON = {
    "rasm.comm": ("rasm.platform", "rasm.knowledge", "rasm.properties"),
    "rasm.knowledge.redis": ("rasm.platform", "rasm.properties", "rasm.comm"),
    "rasm.knowledge.url": ("rasm.platform", "rasm.properties"),
    "rasm.attach": ("rasm.platform", "rasm.knowledge"),
}


@pytest.mark.parametrize(("lower", "higher"), sorted(BUILT_ON.items()), ids=sorted(BUILT_ON))
def test_a_low_layer_imports_nothing_built_on_it(lower: str, higher: tuple[str, ...]) -> None:
    assert lower in MODULES
    upward = {f"{m}: {h}" for h in higher for m in _importers(h) if _under(m, lower)}
    assert upward == set()
