"""``python -m rasm.compiled build|status``: build or inspect rasm's compiled modules."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from rasm.compiled import MODULES, build, folder, status


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m rasm.compiled", description="Build or inspect rasm's compiled modules."
    )
    parser.add_argument("command", choices=["build", "status"])
    parser.add_argument("--force", action="store_true", help="build even when up to date")
    args = parser.parse_args(argv)
    if args.command == "status":
        for name, state in status().items():
            print(f"{name:<32}{state}")
        print(f"folder: {folder()}")
        return 0
    if not args.force and set(status().values()) == {"compiled"}:
        print(f"up to date: {folder()}")
        return 0
    try:
        where = build()
    except ImportError as exc:
        print(f"cannot build: {exc} (pip install 'rasm[compiled]')", file=sys.stderr)
        return 1
    except Exception as exc:  # the C compiler's own message says what failed
        print(f"build failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print(f"compiled {len(MODULES)} modules into {where}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
