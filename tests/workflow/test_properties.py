"""For all valid models (any mix of Python and statechart stages, with or without a modes
chart): the model lints clean, and its skeleton lints clean and runs."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.lint import lint_paths
from rasm.platform.manifest import load_manifest
from rasm.workflow import lint_model, new_app

from .helpers import forget_apps
from .strategies import dump, models

_count = itertools.count()


@pytest.mark.slow
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(model=models())
def test_valid_models_lint_clean_and_generate_apps_that_lint_clean_and_run(
    model: dict, tmp_path_factory
) -> None:
    folder = tmp_path_factory.mktemp(f"gen{next(_count)}")
    model_file = folder / "model.yaml"
    model_file.write_text(dump(model), encoding="utf-8")
    assert lint_model(model_file) == []
    app = folder / "app"
    new_app(app, model_file)
    manifest = load_manifest(app)
    files = [str(manifest.file), *map(str, manifest.properties), *map(str, manifest.rules)]
    assert lint_paths(files) == []
    assert lint_paths([str(app)]) == []  # the app as `rasm lint APP` sees it, its charts too
    assert lint_model(app / "model.yaml") == []
    # each stage is what the model says: its chart, or its class in components.py
    for name, spec in model["components"].items():
        if spec["role"] in manifest.components:
            chart = spec.get("implementation") == "statechart"
            assert (manifest.components[spec["role"]] == f"charts/{name}.yaml") == chart
    carrier = next((c for c in model["components"].values() if "modes" in c), None)
    assert (manifest.modes is not None) == (carrier is not None)
    forget_apps()
    cwd = Path.cwd()
    os.chdir(folder)
    try:
        assert main(["run", str(app), "--clock", "simulated", "--duration", "2"]) == 0
    finally:
        os.chdir(cwd)
        forget_apps()


@settings(max_examples=30, deadline=None)
@given(
    model=models(), stage=st.sampled_from(["monitor", "analyse", "plan", "legitimate", "execute"])
)
def test_removing_a_stage_is_always_reported_at_components(
    model: dict, stage: str, tmp_path_factory
) -> None:
    name = next(n for n, c in model["components"].items() if c["role"] == stage)
    model["components"][name]["role"] = "analyse" if stage != "analyse" else "plan"
    path = tmp_path_factory.mktemp("broken") / "model.yaml"
    text = dump(model)
    path.write_text(text, encoding="utf-8")
    errors = lint_model(path)
    line = text.splitlines().index("components:") + 1
    assert any(
        (e.location.line, e.location.col) == (line, 1) and f"has no {stage} stage" in e.message
        for e in errors
    ), errors
