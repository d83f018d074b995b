"""``rasm`` as the default install runs it, without the ``ros2`` extra: the packages that only
the extra installs cannot be imported, and the import system says so as it says of any
package that is not installed. Usage: ``python tests/ros2/without_extra.py ARGS...`` (the
arguments of ``rasm``)."""

from __future__ import annotations

import importlib.abc
import sys

# what `pip install 'rasm[ros2]'` adds to a default install (pyproject.toml)
EXTRA = {"zenoh", "cyclonedds", "rosbags", "numpy", "xxhash"}


class NotInstalled(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in EXTRA:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


if __name__ == "__main__":
    sys.meta_path.insert(0, NotInstalled())
    from rasm.cli import main

    sys.exit(main(sys.argv[1:]))
