"""``python -m rasm.compiled build|status``: build or inspect rasm's compiled modules."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from rasm.compiled import MODULES, build, folder, status


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m rasm.compiled", description="Build or inspect rasm's compiled modules."
    )
    parser.add_argument("command", choices=["build", "status"])
    parser.add_argument("--force", action="store_true", help="build even when up to date")
    parser.add_argument(
        "--verbose", action="store_true", help="show Cython's and the C compiler's output"
    )
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
        import Cython  # noqa: F401
    except ImportError as exc:
        print(f"cannot build: {exc} (pip install 'rasm[compiled]')", file=sys.stderr)
        return 1
    failure = None
    with _output(args.verbose) as log:
        try:
            where = build()
        except Exception as exc:  # the C compiler's own message (in the log) says what failed
            failure = f"{log().rstrip()[-4000:]}\nbuild failed: {type(exc).__name__}: {exc}"
    if failure is not None:
        print(failure.lstrip(), file=sys.stderr)
        return 1
    print(f"compiled {len(MODULES)} modules into {where}")
    return 0


@contextmanager
def _output(verbose: bool) -> Iterator[Callable[[], str]]:
    """Unless ``verbose``, send what the build prints (the C compiler's warnings included, which
    write to the process's own file descriptors) to a file; yields a function reading it."""
    if verbose:
        yield lambda: ""
        return
    with tempfile.TemporaryDirectory(prefix="rasm-compiled-log-") as scratch:
        path = Path(scratch) / "build.log"
        sys.stdout.flush()
        sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        with open(path, "wb") as sink:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            try:
                yield lambda: path.read_text(errors="replace")
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                os.close(saved[0])
                os.close(saved[1])


if __name__ == "__main__":
    raise SystemExit(main())
