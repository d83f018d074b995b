"""The public face: ``import rasm`` gives the names an application is written with."""

from __future__ import annotations

import subprocess
import sys

import rasm

PUBLIC = {
    "Action",
    "Clock",
    "Anomaly",
    "Plan",
    "Platform",
    "RasmError",
    "Role",
    "RunOptions",
    "RunSummary",
    "SourceError",
    "StageContext",
    "__version__",
    "compile_properties",
    "load_manifest",
}


def test_import_rasm_gives_the_application_names() -> None:
    assert set(rasm.__all__) == PUBLIC
    for name in PUBLIC:
        assert getattr(rasm, name) is not None, name
    assert issubclass(rasm.SourceError, rasm.RasmError)
    assert rasm.Plan({"mode": "boost"})["mode"] == "boost"


def test_rasm_platform_gives_its_public_names_and_no_others() -> None:
    import rasm.platform

    assert set(rasm.platform.__all__) == {
        "Action",
        "Anomaly",
        "AppManifest",
        "ChartStage",
        "Clock",
        "LoopStats",
        "Plan",
        "Platform",
        "Role",
        "RunOptions",
        "RunSummary",
        "StageContext",
        "load_manifest",
    }
    for name in rasm.platform.__all__:
        assert getattr(rasm.platform, name) is not None, name
    assert rasm.platform.Platform is rasm.Platform
    try:
        rasm.platform.Telegraf  # noqa: B018 - a building block: imported from its own module
    except AttributeError:
        pass
    else:
        raise AssertionError("rasm.platform.Telegraf should not be a public name")


def test_an_unknown_name_is_an_attribute_error() -> None:
    try:
        rasm.Nothing  # noqa: B018
    except AttributeError as exc:
        assert "Nothing" in str(exc)
    else:
        raise AssertionError("rasm.Nothing should not exist")


def test_import_rasm_loads_no_platform_until_asked() -> None:
    code = "import sys, rasm, rasm.platform; print('rasm.platform.platform' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_rasm_version_prints_the_package_version() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "--version"], capture_output=True, text=True
    )
    assert out.returncode == 0
    assert out.stdout.strip() == f"rasm {rasm.__version__}"


def test_each_face_lists_its_public_names_and_names_itself_in_an_unknown_names_error() -> None:
    import rasm.platform

    for face in (rasm, rasm.platform):
        assert dir(face) == sorted(face.__all__)
        try:
            face.Nothing  # noqa: B018
        except AttributeError as exc:
            assert str(exc) == f"module {face.__name__!r} has no attribute 'Nothing'"
        else:
            raise AssertionError(f"{face.__name__}.Nothing should not exist")
