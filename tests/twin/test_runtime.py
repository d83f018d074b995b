"""The Hotbox's twin inside rasm's runtime: residuals and model versions in the trace, and a
lighter content change raising drift."""

from __future__ import annotations

import dataclasses

from rasm import Platform, RunOptions
from rasm.testing.apps import app_manifest
from tests.twin.hotbox import APP, HotboxTwin, box


def run(scenario, seed=1, duration=90.0):
    manifest = dataclasses.replace(app_manifest(APP), twin=None)
    twin = HotboxTwin()
    platform = Platform(
        manifest,
        RunOptions(
            clock="simulated",
            seed=seed,
            knowledge="memory",
            scenario=scenario,
            components={"twin": twin},
        ),
    )
    records = []
    platform.on_record.append(lambda time, record: records.append((time, dict(record))))
    platform.build()
    platform.assembly.managed_system.simulator = box(500.0, 2.0, 12.0)(scenario, seed)
    platform.run(duration)
    return platform, records


SCENARIO = {"first_lid_opening": 8.0, "lid_every": 30.0, "lid_open_for": 12.0}


def test_the_runtime_records_the_twins_residual_and_model_versions():
    platform, records = run(SCENARIO)
    residuals = [r["twin_residual"] for _, r in records if "twin_residual" in r]
    assert residuals and max(residuals) < 0.2  # the nominal box: sensor noise only
    versions = [r["twin_model_version"] for _, r in records if "twin_model_version" in r]
    assert versions and versions == sorted(versions) and versions[0] == 1
    assert platform.managing.knowledge.store.read_knowledge("twin_model")["version"] == versions[-1]
    assert not [t for t, r in records if r.get("drift")]


def test_a_lighter_content_raises_drift_in_the_runtime():
    _, records = run({**SCENARIO, "content_change": [[40.0, 200.0]]})
    drifts = [t for t, r in records if r.get("drift") is True]
    assert drifts and 40.0 < drifts[0] <= 55.0
