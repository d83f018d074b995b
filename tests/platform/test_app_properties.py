"""The properties a run checks: the platform's own and the app's, each name defined once."""

from __future__ import annotations

import shutil

import pytest

from rasm.errors import PlatformError
from rasm.platform.app_properties import compile_app_properties
from rasm.platform.manifest import load_manifest
from rasm.resources import data_dir

from .conftest import HOTBOX


def hotbox_with(folder, extra_rv):
    """The Hotbox with one more property file, ``properties/extra.rv``."""
    shutil.copytree(HOTBOX, folder, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    (folder / "properties" / "extra.rv").write_text(extra_rv, encoding="utf-8")
    app = folder / "app.yaml"
    text = app.read_text(encoding="utf-8")
    app.write_text(
        text.replace(
            "  - properties/hotbox.rv\n", "  - properties/hotbox.rv\n  - properties/extra.rv\n"
        ),
        encoding="utf-8",
    )
    return load_manifest(folder)


def test_the_platforms_properties_come_first_then_the_apps_in_their_order(tmp_path):
    m = hotbox_with(
        tmp_path / "app", "input temperature: float\nproperty warm:\n  always (temperature > 0.0)\n"
    )
    monitors = compile_app_properties(m)
    own = sorted(data_dir("properties").glob("*.rv"))
    assert len(monitors) == len(own) + 2
    assert "stage_order" in monitors[len(own) - 1].properties  # maple_k.rv, the last of its own
    assert "temperature_band" in monitors[-2].properties and list(monitors[-1].properties) == [
        "warm"
    ]


def test_a_property_name_the_app_defines_twice_is_refused_naming_both_files(tmp_path):
    m = hotbox_with(
        tmp_path / "app",
        "input temperature: float\nproperty temperature_band:\n  always (temperature > 0.0)\n",
    )
    with pytest.raises(PlatformError) as caught:
        compile_app_properties(m)
    message = str(caught.value)
    assert "'temperature_band'" in message and "extra.rv" in message and "hotbox.rv" in message


def test_an_app_property_named_like_one_of_the_platforms_is_refused(tmp_path):
    m = hotbox_with(
        tmp_path / "app", "event executed\nproperty loop_alive:\n  always (not executed)\n"
    )
    with pytest.raises(
        PlatformError, match=r"'loop_alive' of .*extra\.rv is already defined in .*maple_k\.rv"
    ):
        compile_app_properties(m)
