"""The distribution modules respect the layering: knowledge and comm import no higher layer."""

from __future__ import annotations

import ast
from pathlib import Path

import rasm

ROOT = Path(rasm.__file__).parent
RULES = {
    "knowledge/redis.py": ("rasm.properties", "rasm.platform", "rasm.comm"),
    "knowledge/url.py": ("rasm.properties", "rasm.platform"),
    "comm/influx.py": ("rasm.properties", "rasm.platform", "rasm.knowledge"),
    "comm/signing.py": ("rasm.properties", "rasm.platform", "rasm.knowledge"),
    "comm/presence.py": ("rasm.properties", "rasm.platform", "rasm.knowledge"),
    "attach.py": ("rasm.platform", "rasm.knowledge"),
}


def _imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def test_no_module_imports_a_layer_above_it():
    offenders = [
        f"{name}: {module}"
        for name, forbidden in RULES.items()
        for module in _imports(ROOT / name)
        if any(module == f or module.startswith(f + ".") for f in forbidden)
    ]
    assert offenders == []
    assert all(_imports(ROOT / name) for name in RULES)  # the files exist and were read
