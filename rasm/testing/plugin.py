"""The rasm pytest plugin (registered through the ``pytest11`` entry point).

Installing rasm makes it available to every pytest run:

* the ``rasm_app`` fixture runs an application on the simulated clock and returns its
  :class:`~rasm.testing.Trace` (session-scoped, so ``@given`` tests may use it)::

      def test_hotbox_adapts(rasm_app):
          trace = rasm_app("examples/hotbox", seed=1, duration=30)
          assert_properties("examples/hotbox/properties/hotbox.rv", trace)

* the ``--rasm-failures DIR`` option says where failing traces and event sequences are saved
  (default ``.rasm/failures``), and the end of the run lists the files saved.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

__all__ = ["AppRunner", "rasm_app"]


class AppRunner:
    """What the ``rasm_app`` fixture gives: ``rasm_app(app, seed=0, duration=None, ...)``."""

    def __call__(
        self,
        app: Any,
        *,
        seed: int = 0,
        duration: float | None = None,
        scenario: dict[str, Any] | None = None,
        **kwargs: Any,
    ):
        """Run ``app`` (folder or manifest); ``duration`` defaults to the manifest's.

        Other keyword arguments go to :func:`rasm.testing.run_app` (``components``, ``trace``,
        manifest overrides such as ``stage_budget``).
        """
        from rasm.testing.apps import app_manifest, run_app

        if duration is None:
            duration = app_manifest(app).duration
        return run_app(app, seed=seed, duration=duration, scenario=scenario, **kwargs)


@pytest.fixture(scope="session")
def rasm_app() -> AppRunner:
    """Run an application on the simulated clock: ``rasm_app(app, seed=1, duration=30)``."""
    return AppRunner()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("rasm")
    group.addoption(
        "--rasm-failures",
        default=None,
        metavar="DIR",
        help="where rasm.testing saves failing traces and event sequences "
        "(default: $RASM_FAILURES or .rasm/failures)",
    )


def pytest_configure(config: pytest.Config) -> None:
    folder = config.getoption("--rasm-failures", default=None)
    if folder:
        os.environ["RASM_FAILURES"] = str(Path(folder).resolve())


_REPORTED: list[Path] = []


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item):
    import sys

    failures = sys.modules.get("rasm.testing.failures")
    before = len(failures.saved_files()) if failures is not None else 0
    try:
        return (yield)
    except BaseException:
        # files saved by a test that failed (not by one that expected a failure and caught it)
        failures = sys.modules.get("rasm.testing.failures")
        if failures is not None:
            _REPORTED.extend(failures.saved_files()[before:])
        raise


def pytest_terminal_summary(terminalreporter: Any) -> None:
    saved = [p for p in dict.fromkeys(_REPORTED) if p.exists()]
    if saved:
        terminalreporter.section("rasm: failing examples saved")
        for path in saved:
            terminalreporter.write_line(f"{path}")
