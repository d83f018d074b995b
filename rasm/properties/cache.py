"""The user's cache folder for the property language: lark's parser tables
(:mod:`rasm.properties.parser`) and the checked specifications of property files
(:func:`rasm.properties.loader.cached_specification`), kept between runs.

Both are pickles, and unpickling runs code: only a folder and files this user owns, that no one
else can write, are read back.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_folder", "trusted"]


def cache_folder() -> Path | None:
    """``rasm`` in the user's cache folder, made if missing; None where there is none to trust
    (no home, a read-only one, a folder others can write to)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    folder = Path(base) / "rasm"
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        return folder if trusted(folder.stat()) else None
    except OSError:
        return None


def trusted(info: os.stat_result) -> bool:
    """Whether a cache file or folder with this status may be read back: only what this user
    owns and no one else can write."""
    getuid = getattr(os, "getuid", None)
    if getuid is None:  # no owners to compare: no cache
        return False
    return info.st_uid == getuid() and not info.st_mode & 0o022
