"""``scenarios(app)``: a hypothesis strategy of the disturbance schedules an application declares.

A *scenario* is the dict ``app.yaml`` gives under ``managed_system.scenario`` and the simulator
receives as ``Simulator(scenario=..., seed=...)``. An application declares the space of its
scenarios on its simulator class, as ``SCENARIOS``: a hypothesis strategy of scenario dicts, or a
function of the run's ``duration`` (seconds, or None) returning one::

    class HotboxSimulator:
        @staticmethod
        def SCENARIOS(duration):
            from hypothesis import assume
from hypothesis import strategies as st
            from rasm.testing import windows
            return st.fixed_dictionaries({"openings": windows(within=duration or 40)})

Where a simulator declares nothing, :func:`scenarios` falls back, in this order, on

1. a space rasm knows for a shipped example (:data:`KNOWN_SPACES`, by app name: the Hotbox's lid
   openings, ``{"openings": [[start, length], ...]}``);
2. the app's default scenario with each number varied between 0 and twice its value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hypothesis import assume
from hypothesis import strategies as st

from rasm.platform.loading import load_component
from rasm.platform.manifest import AppManifest
from rasm.testing.apps import app_manifest

__all__ = ["scenarios", "windows", "KNOWN_SPACES", "simulator_class"]


def windows(
    *,
    within: float = 40.0,
    length: tuple[float, float] = (0.5, 15.0),
    min_count: int = 1,
    max_count: int = 3,
    step: float = 0.5,
) -> st.SearchStrategy[list[list[float]]]:
    """Disturbance windows ``[[start, length], ...]``: sorted, not overlapping, on a ``step`` grid.

    Starts lie in ``[0, within]``, lengths in ``length``. Shrinks towards fewer, earlier and
    shorter windows.
    """
    low, high = length
    if not (0 < step and 0 <= low <= high and within >= 0 and 0 <= min_count <= max_count):
        raise ValueError(
            "windows() needs step > 0, 0 <= length[0] <= length[1], within >= 0 and "
            f"0 <= min_count <= max_count; got step={step}, length={length}, within={within}, "
            f"min_count={min_count}, max_count={max_count}"
        )
    gaps = st.integers(0, math.floor(within / step))
    sizes = st.integers(math.ceil(low / step), math.floor(high / step))

    @st.composite
    def build(draw: st.DrawFn) -> list[list[float]]:
        drawn = draw(st.lists(st.tuples(gaps, sizes), min_size=min_count, max_size=max_count))
        out: list[list[float]] = []
        start = 0
        for gap, size in drawn:  # each window starts `gap` steps after the previous one ends
            start += gap
            if start * step > within:
                break
            out.append([round(start * step, 6), round(size * step, 6)])
            start += size
        assume(len(out) >= min_count)
        return out

    return build()


def _hotbox(duration: float | None) -> st.SearchStrategy[dict[str, Any]]:
    # the lid opens one to three times during the run, each time for 0.5 to 15 s
    within = max((duration or 40.0) - 5.0, 1.0)
    return st.fixed_dictionaries({"openings": windows(within=within, max_count=3)})


KNOWN_SPACES: dict[str, Callable[[float | None], st.SearchStrategy[dict[str, Any]]]] = {
    "hotbox": _hotbox,
}
"""Scenario spaces of shipped examples that do not declare ``SCENARIOS`` themselves."""


def simulator_class(manifest: AppManifest) -> type | None:
    """The class of the app's simulator (None if the app has none)."""
    if not manifest.simulator:
        return None
    instance = load_component(
        manifest.simulator,
        manifest.folder,
        package=f"rasm_app_{manifest.name}",
        kwargs={"scenario": dict(manifest.scenario), "seed": 0},
    )
    return type(instance)


def _varied_defaults(manifest: AppManifest) -> st.SearchStrategy[dict[str, Any]]:
    numbers = {
        k: v
        for k, v in manifest.scenario.items()
        if isinstance(v, int | float) and not isinstance(v, bool)
    }
    if not numbers:
        raise ValueError(
            f"app {manifest.name!r} declares no scenario space: give its simulator class a "
            f"SCENARIOS attribute (a hypothesis strategy of scenario dicts, or a function of the "
            f"duration returning one; see docs/testing.md), or pass scenarios to run_app yourself"
        )
    varied: dict[str, st.SearchStrategy[Any]] = {}
    for key, value in numbers.items():
        if isinstance(value, int):
            varied[key] = st.integers(0, max(2 * value, 0))
        else:
            varied[key] = st.floats(0.0, max(2.0 * value, 0.0)).map(lambda x: round(x, 3))
    fixed = {k: st.just(v) for k, v in manifest.scenario.items() if k not in numbers}
    return st.fixed_dictionaries({**fixed, **varied})


def scenarios(
    app: str | Path | AppManifest, *, duration: float | None = None
) -> st.SearchStrategy[dict[str, Any]]:
    """The disturbance schedules ``app`` declares, as a strategy (see the module documentation).

    ``duration`` is the length of the runs the scenarios are for; spaces that place disturbances
    in time keep them inside it.
    """
    manifest = app_manifest(app)
    cls = simulator_class(manifest)
    declared = getattr(cls, "SCENARIOS", None) if cls is not None else None
    if declared is not None:
        space = declared if isinstance(declared, st.SearchStrategy) else declared(duration)
        if not isinstance(space, st.SearchStrategy):
            raise TypeError(
                f"{cls.__name__}.SCENARIOS must be a hypothesis strategy or a function of the "
                f"duration returning one, not {type(space).__name__}"
            )
        return space
    if manifest.name in KNOWN_SPACES:
        return KNOWN_SPACES[manifest.name](duration)
    return _varied_defaults(manifest)
