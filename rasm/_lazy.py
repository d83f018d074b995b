"""Package faces whose public names are loaded on first use, so importing the package (and
every ``rasm`` command) stays cheap."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(
    namespace: dict[str, Any], public: Mapping[str, str]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """A package's module ``__getattr__`` and ``__dir__`` for ``public`` (name -> the module
    that defines it): a name is imported on first use and bound in ``namespace`` (the
    package's ``globals()``), so later reads find it directly; ``dir()`` lists ``__all__``."""
    package = namespace["__name__"]

    def __getattr__(name: str) -> object:
        module = public.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(namespace["__all__"])

    return __getattr__, __dir__
