"""The compiled build of rasm's hot modules: the same Python source, compiled by Cython.

The modules a MAPLE-K iteration spends its time in (the fast statechart interpreter, the blocks,
the record path, knowledge, the bus, the online monitors' operators) run faster compiled (the
Hotbox about 1.45 times); nothing else changes, because the source is the same. The build is
optional and is never stale:

- ``python -m rasm.compiled build`` compiles :data:`MODULES` into a folder of the environment
  (:func:`folder`), with a manifest holding the SHA-256 of each source it compiled;
- importing ``rasm`` installs a finder that loads a module's compiled form only while the source
  that Python would import is byte-identical to the one compiled: an edited module runs as plain
  Python until the next build, so a stale build can never run;
- ``RASM_PURE_PYTHON=1`` turns the compiled build off (for debugging, coverage or profiling);
  ``RASM_COMPILED_DIR`` chooses another folder.

``python -m rasm.compiled status`` says, module by module, which form an import would take.
Building needs Cython and a C compiler (``pip install 'rasm[compiled]'``); without them rasm runs
as plain Python. See docs/performance-statecharts.md for what it measures.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import json
import os
import sys
import sysconfig
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "MODULES", "SourceChangedError", "build", "folder", "install", "loaded", "source_of", "status",
]

# The modules worth compiling: where the loop spends its time (profiled with py-spy, see
# docs/performance-statecharts.md). Others gain little and would only make the build longer.
MODULES: tuple[str, ...] = (
    "rasm.statechart.clock",
    "rasm.statechart.fast",
    "rasm.statechart.fast_tables",
    "rasm.statechart.interpreter",
    "rasm.platform.block",
    "rasm.platform.blocks",
    "rasm.platform.components",
    "rasm.platform.orchestrator",
    "rasm.platform.runtime",
    "rasm.platform.scheduler",
    "rasm.platform.stages",
    "rasm.platform.trace",
    "rasm.knowledge.base",
    "rasm.comm.envelope",
    "rasm.comm.local",
    "rasm.comm.message",
    "rasm.comm.topics",
    "rasm.comm.transport",
    "rasm.spec.operators",
    "rasm.testing.apps",
    "rasm.twin.rls",
)

MANIFEST = "manifest.json"
# Annotations stay annotations: with typing on, Cython would enforce them at run time (a tuple
# default for a ``list[...]`` parameter would raise), which plain Python never does.
_DIRECTIVES = {"annotation_typing": False, "language_level": 3}
# Where Cython computes in C doubles (float() locals, see rasm.twin.rls) the compiler must not
# fuse a multiply and an add into one instruction (one rounding instead of Python's two).
_C_FLAGS = ["-ffp-contract=off"]


def folder() -> Path:
    """Where the compiled build lives: ``RASM_COMPILED_DIR``, else a folder of the environment
    named for this interpreter's extension tag (one build per Python version and platform)."""
    chosen = os.environ.get("RASM_COMPILED_DIR")
    base = Path(chosen) if chosen else Path(sys.prefix) / "share" / "rasm-compiled"
    return base / _tag()


def _tag() -> str:
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    return suffix.strip(".").rsplit(".", 1)[0]


def _off() -> bool:
    return os.environ.get("RASM_PURE_PYTHON", "") not in ("", "0")


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def source_of(name: str, path: Sequence[str] | None = None) -> Path | None:
    """The source file Python's own finders would import for module ``name``, if any (also
    for a module imported compiled, whose ``__file__`` is its binary)."""
    if path is None:  # the package's own search path (importing it, if need be)
        path = importlib.import_module(name.rpartition(".")[0]).__path__
    spec = importlib.machinery.PathFinder.find_spec(name, path)
    if spec is None or not isinstance(spec.loader, importlib.machinery.SourceFileLoader):
        return None
    return Path(spec.origin) if spec.origin else None


def _read_manifest(where: Path) -> dict[str, Any]:
    try:
        return json.loads((where / MANIFEST).read_text())["modules"]
    except (OSError, ValueError, KeyError, TypeError):
        return {}


class _CompiledFinder:
    """A meta path finder that hands out a compiled module while its source is unchanged."""

    def __init__(self, where: Path, entries: dict[str, Any]) -> None:
        self.where = where
        self.entries = entries
        self.loaded: set[str] = set()

    def find_spec(self, name: str, path: Sequence[str] | None, target: Any = None) -> Any:
        entry = self.entries.get(name)
        if entry is None:
            return None
        source = source_of(name, path)
        binary = self.where / entry["file"]
        if source is None or not binary.is_file() or _digest(source) != entry["sha256"]:
            return None  # edited since the build (or not built here): plain Python
        spec = importlib.util.spec_from_file_location(name, binary)
        if spec is not None:
            self.loaded.add(name)
        return spec

    def invalidate_caches(self) -> None:
        pass


_finder: _CompiledFinder | None = None


def install() -> bool:
    """Put the compiled build's finder first on ``sys.meta_path`` (back in front if another
    finder was put before it since); False when there is no build here or ``RASM_PURE_PYTHON``
    is set. ``rasm/__init__`` calls it, and ``rasm.testing`` again (see there)."""
    global _finder
    if _finder is not None:
        if sys.meta_path[:1] != [_finder]:
            if _finder in sys.meta_path:
                sys.meta_path.remove(_finder)
            sys.meta_path.insert(0, _finder)
        return True
    if _off():
        return False
    where = folder()
    entries = _read_manifest(where)
    if not entries:
        return False
    _finder = _CompiledFinder(where, entries)
    # first: pytest's assertion rewriter, earlier on the path, would otherwise take the source
    sys.meta_path.insert(0, _finder)
    return True


def loaded() -> frozenset[str]:
    """The modules imported in their compiled form so far."""
    return frozenset() if _finder is None else frozenset(_finder.loaded)


def status(modules: Iterable[str] = MODULES) -> dict[str, str]:
    """Per module, what an import would take: ``compiled``, ``stale`` (edited since the build:
    plain Python), ``not built`` or ``off`` (``RASM_PURE_PYTHON``)."""
    off = _off()
    where = folder()
    entries = _read_manifest(where)
    found = {}
    for name in modules:
        entry = entries.get(name)
        if off:
            found[name] = "off"
        elif entry is None or not (where / entry["file"]).is_file():
            found[name] = "not built"
        else:
            source = source_of(name)
            fresh = source is not None and _digest(source) == entry["sha256"]
            found[name] = "compiled" if fresh else "stale"
    return found


class SourceChangedError(RuntimeError):
    """A module's source changed while :func:`build` compiled it (nothing was installed)."""


def build(
    modules: Iterable[str] = MODULES, *, into: Path | None = None, jobs: int | None = None
) -> Path:
    """Compile ``modules`` (their sources as Python would import them now) into ``into`` (by
    default :func:`folder`) and write its manifest. Needs Cython and a C compiler; raises
    ``ImportError`` without Cython and the compiler's error when a module fails to build."""
    import shutil
    import tempfile

    from Cython.Build import cythonize
    from setuptools import Distribution, Extension

    where = folder() if into is None else into
    sources = {}
    for name in modules:
        source = source_of(name)
        if source is None:
            raise FileNotFoundError(f"no Python source for module {name}")
        sources[name] = source
    # Digests taken before compiling: a source edited while the build runs must not be recorded
    # as the source of a binary compiled from its older text (checked again after the build).
    digests = {name: _digest(source) for name, source in sources.items()}
    with tempfile.TemporaryDirectory(prefix="rasm-compiled-") as scratch:
        staged = Path(scratch) / "out"
        extensions = cythonize(
            [
                Extension(name, [str(source)], extra_compile_args=_C_FLAGS)
                for name, source in sources.items()
            ],
            build_dir=str(Path(scratch) / "c"),
            compiler_directives=_DIRECTIVES,
            quiet=True,
            nthreads=jobs or os.cpu_count() or 1,
        )
        dist = Distribution({"name": "rasm-compiled", "ext_modules": extensions})
        command = dist.get_command_obj("build_ext")
        command.build_lib = str(staged)
        command.build_temp = str(Path(scratch) / "tmp")
        command.parallel = jobs or os.cpu_count() or 1
        dist.run_command("build_ext")
        edited = [str(s) for name, s in sources.items() if _digest(s) != digests[name]]
        if edited:
            raise SourceChangedError(
                f"edited while it was being compiled: {', '.join(edited)}; the build there was is "
                "kept: build again once the edits are done"
            )
        suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
        entries = {}
        for name, source in sources.items():
            file = name.replace(".", "/") + suffix
            entries[name] = {"file": file, "sha256": digests[name], "source": str(source)}
        # replace the old build whole, so that no binary outlives its manifest entry
        if where.exists():
            shutil.rmtree(where)
        where.mkdir(parents=True)
        for entry in entries.values():
            target = where / entry["file"]
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(staged / entry["file"], target)
        (where / MANIFEST).write_text(json.dumps({"modules": entries}, indent=1) + "\n")
    return where
