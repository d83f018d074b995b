"""rasm.comm sits low in the platform: it must not import the layers built on it."""

from __future__ import annotations

import ast
from pathlib import Path

import rasm.comm

FORBIDDEN = ("rasm.platform", "rasm.knowledge", "rasm.properties")


def test_comm_imports_no_higher_layer():
    offenders = []
    for path in Path(rasm.comm.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [
                f"{path.name}:{node.lineno}: {name}"
                for name in names
                if any(name == f or name.startswith(f + ".") for f in FORBIDDEN)
            ]
    assert offenders == []
