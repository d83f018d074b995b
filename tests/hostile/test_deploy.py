"""`rasm deploy` verifies every entry before it writes anything; a refused package leaves the
target untouched and says why in one line (exit 2, no traceback, no raw OS error)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.cli import main
from rasm.workflow.integrity import digest

from .packages import UNIT, WORKFLOWS, build, files, unit_config, written


@pytest.fixture(autouse=True)
def _no_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RASM_PACKAGE_KEY", raising=False)
    monkeypatch.delenv("RASM_PACKAGE_KEY_FILE", raising=False)


def deploy(capsys: pytest.CaptureFixture[str], package: Path, target: Path) -> tuple[int, str]:
    code = main(["deploy", str(package), "--unit", UNIT, "--to", str(target)])
    out = capsys.readouterr()
    return code, out.err + out.out


def assert_refused(code: int, out: str, target: Path, words: str) -> None:
    assert "Traceback" not in out and "Errno" not in out, out
    assert code == 2, out
    assert words in out, out
    assert written(target) == []


def test_a_minimal_package_deploys_and_runs_its_workflow(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out = deploy(capsys, build(tmp_path / "p.zip", files()), tmp_path / "t")
    assert code == 0, out
    assert (tmp_path / "t" / "installed").is_file()
    assert (tmp_path / "t" / "package" / "05_Actions" / "install.sh").is_file()


def test_a_file_that_is_also_a_folder_of_another_entry_is_refused_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    contents = files(**{"02_Nodes__x": b"a file", "02_Nodes__x__file": b"inside x"})
    code, out = deploy(capsys, build(tmp_path / "p.zip", contents), tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", "02_Nodes/x: both a file and the folder of")


@pytest.mark.parametrize("name", ["02_Nodes//x", "./02_Nodes/x", "02_Nodes/./x", "a\x01b"])
def test_an_entry_not_in_plain_form_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    contents = {**files(), name: b"x"}
    code, out = deploy(capsys, build(tmp_path / "p.zip", contents), tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", "")


def test_a_name_too_long_for_the_file_system_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    contents = {**files(), "02_Nodes/" + "n" * 300: b"x"}
    code, out = deploy(capsys, build(tmp_path / "p.zip", contents), tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", "longer than 255 bytes")


@pytest.mark.parametrize(
    "config,words",
    [
        ("just text", "a unit's configuration is a mapping"),
        (json.dumps({k: v for k, v in unit_config().items() if k != "arch"}), "'arch'"),
        (json.dumps(unit_config(role=["a", "list"])), "'role' must be a non-empty string"),
        ("unit: [" * 200, "nested more than"),
        ("unit: 2021-02-30", "day is out of range"),
    ],
)
def test_a_bad_unit_configuration_is_refused_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], config: str, words: str
) -> None:
    contents = {**files(), f"04_Platform/{UNIT}.yaml": config.encode()}
    code, out = deploy(capsys, build(tmp_path / "p.zip", contents), tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", words)


@pytest.mark.parametrize(
    "workflows,words",
    [
        ({"workflows": {}, "actions": {}}, "no workflow 'deploy'"),
        ({**WORKFLOWS, "actions": {"install": "05_Actions/missing.sh"}}, "not a file of"),
        ({**WORKFLOWS, "workflows": {"deploy": {"steps": ["fly"]}}}, "'fly' is not an action"),
        ({"workflows": ["deploy"]}, "must be mappings"),
    ],
)
def test_bad_workflows_are_refused_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], workflows: object, words: str
) -> None:
    contents = {**files(), "06_Workflows/workflows.yaml": json.dumps(workflows).encode()}
    code, out = deploy(capsys, build(tmp_path / "p.zip", contents), tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", words)


@pytest.mark.parametrize(
    "manifest,words",
    [
        (b"[" * 100_000, "not JSON"),
        (b"\xff\xfe", "not JSON"),
        (json.dumps({"files": {}, "units": [{"a": 1}]}).encode(), "not listed"),
        (json.dumps({"files": []}).encode(), "no file list"),
    ],
)
def test_a_bad_manifest_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], manifest: bytes, words: str
) -> None:
    package = build(tmp_path / "p.zip", files(), manifest=manifest)
    code, out = deploy(capsys, package, tmp_path / "t")
    assert_refused(code, out, tmp_path / "t", words)


def test_a_target_that_is_a_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "t"
    target.write_text("not a folder")
    code, out = deploy(capsys, build(tmp_path / "p.zip", files()), target)
    assert code == 2 and "not a folder" in out and "Traceback" not in out
    assert target.read_text() == "not a folder"


# entry names from path segments, mostly plain ones; '02_Nodes/x' and '02_Nodes/x/y' may meet
_PLAIN = ["02_Nodes", "x", "y", "05_Actions", "install.sh"]
_ODD = [".", "..", "", "a\\b", "c\x01", "d" * 256]
_NAMES = st.lists(
    st.sampled_from(_PLAIN * 6 + _ODD), min_size=1, max_size=3
).map("/".join).filter(bool)  # zipfile itself cannot write an empty name
# mostly a good configuration; else any bytes
_CONFIG = st.sampled_from([None, None, None, b""]).flatmap(
    lambda c: st.just(c) if c is None else st.binary(max_size=30)
)


@settings(
    max_examples=80, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    extra=st.dictionaries(_NAMES, st.binary(max_size=4), max_size=3),
    unlisted=st.lists(_NAMES, max_size=1),
    config=_CONFIG,
)
def test_any_package_either_deploys_or_is_refused_having_written_nothing(
    tmp_path_factory: pytest.TempPathFactory,
    capsys: pytest.CaptureFixture[str],
    extra: dict[str, bytes],
    unlisted: list[str],
    config: bytes | None,
) -> None:
    work = tmp_path_factory.mktemp("fuzz")
    contents = {**files(), **extra}
    if config is not None:
        contents[f"04_Platform/{UNIT}.yaml"] = config
    listed = {name: digest(data) for name, data in contents.items()}
    for name in unlisted:  # listed in the manifest, missing from the zip
        listed.setdefault(name, "0" * 64)
    package = build(work / "p.zip", contents, listed=listed)
    code, out = deploy(capsys, package, work / "t")
    assert "Traceback" not in out and "Errno" not in out, out
    assert not any(ord(c) < 32 and c != "\n" for c in out), out  # names shown escaped
    assert code in (0, 2), out
    if code == 2:
        assert written(work / "t") == []
    else:
        assert (work / "t" / "installed").is_file()
