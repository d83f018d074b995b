"""Helpers that generated applications import at run time (kept tiny and stable)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

__all__ = ["load_sibling"]


def load_sibling(caller: str, file: str, name: str) -> ModuleType:
    """Import the module ``name`` from the folder of ``file`` (an app's ``messages.py``).

    ``caller`` is the importing module's ``__name__``: the sibling is registered in the same
    package (``rasm_app_NAME.messages`` beside ``rasm_app_NAME.components``), so an app loaded by
    the platform, by its tests or from an installed wheel shares one copy.
    """
    package = caller.rpartition(".")[0] or "rasm_app"
    qualified = f"{package}.{name}"
    module = sys.modules.get(qualified)
    if module is not None:
        return module
    path = Path(file).resolve().parent / f"{name}.py"
    spec = importlib.util.spec_from_file_location(qualified, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[qualified] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[qualified]
        raise
    return module
