"""rasm's optional dependencies: which extra of ``pip install 'rasm[...]'`` brings which
package, and the error that says which one to install when a package is missing."""

from __future__ import annotations

from rasm.errors import RasmError

__all__ = ["EXTRAS", "MissingExtra", "missing_extra"]

#: extra -> what it adds, and the top-level modules of the packages only it installs
#: (pyproject.toml)
EXTRAS = {
    "ros2": ("ROS 2 support", ("zenoh", "cyclonedds", "rosbags", "numpy", "xxhash")),
    "cluster": ("Dask distributed", ("distributed", "dask")),
}
_EXTRA_OF = {module: extra for extra, (_, modules) in EXTRAS.items() for module in modules}


class MissingExtra(RasmError, ModuleNotFoundError):
    """Something needs a package of an extra that is not installed (``name``: its module)."""


def missing_extra(exc: ImportError, needed_by: str) -> MissingExtra | None:
    """The :class:`MissingExtra` ``exc`` means (for what ``needed_by`` names), or None when
    the missing module is none of an extra's."""
    module = (exc.name or "").partition(".")[0]
    extra = _EXTRA_OF.get(module)
    if extra is None:
        return None
    return MissingExtra(
        f"{needed_by} needs rasm's {EXTRAS[extra][0]}, which is not installed (no module named "
        f"{module!r}); install it with: pip install 'rasm[{extra}]'",
        name=module,
    )
