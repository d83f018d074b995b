"""``rasm deploy``: verify a package, install one compute unit from it, validate, start.

Nothing is written before the whole package is verified: every file's SHA-256 against
``MANIFEST.json``, no file missing or unlisted, no path leaving the target, and the HMAC-SHA256
signature when a key is configured. Then the package is extracted to ``DIR/package``, the unit's
variables are written to ``DIR/unit.env``, and the workflow ``deploy`` of
``06_Workflows/workflows.yaml`` runs its actions (``05_Actions/*.sh``): install from
``01_Binaries`` into ``DIR/venv`` with ``pip --no-index``, then validate. ``start=True`` also runs
the workflow ``start`` (the unit's nodes in the background).
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import yaml

from rasm.errors import RasmError
from rasm.workflow.derive import host_arch
from rasm.workflow.integrity import (
    MANIFEST,
    SIGNATURE,
    IntegrityError,
    verify_files,
    verify_signature,
)

__all__ = [
    "DeployError",
    "DeployReport",
    "StepResult",
    "deploy_package",
    "read_package",
    "run_workflow",
]


class DeployError(RasmError):
    """The unit cannot be deployed: unknown unit, wrong CPU, or a failed action."""


@dataclass
class StepResult:
    """One action of a workflow: its name, exit code and output."""

    action: str
    returncode: int
    output: str

    @property
    def ok(self) -> bool:
        return self.returncode == 0


@dataclass
class DeployReport:
    """What ``rasm deploy`` did."""

    target: Path
    unit: str
    role: str
    files: int
    signature: str
    steps: list[StepResult] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(step.ok for step in self.steps)


def read_package(
    package: str | Path, key: bytes | None
) -> tuple[dict[str, Any], dict[str, bytes], str]:
    """The verified manifest and contents of a package; raises :class:`IntegrityError`."""
    path = Path(package)
    try:
        with zipfile.ZipFile(path) as archive:
            contents = {}
            for info in archive.infolist():
                if info.is_dir():
                    continue
                name = PurePosixPath(info.filename)
                if name.is_absolute() or ".." in name.parts or "\\" in info.filename:
                    raise IntegrityError(f"{info.filename}: a path outside the package")
                if info.filename in contents:
                    raise IntegrityError(f"{info.filename}: appears twice in the package")
                contents[info.filename] = archive.read(info)
    except zipfile.BadZipFile as exc:
        raise IntegrityError(f"{path}: not a package (bad zip: {exc})") from None
    except FileNotFoundError:
        raise IntegrityError(f"{path}: no such package") from None
    if MANIFEST not in contents:
        raise IntegrityError(f"{path}: no {MANIFEST}: not a rasm package")
    raw = contents[MANIFEST]
    signature = verify_signature(raw, contents.get(SIGNATURE), key)
    try:
        manifest = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise IntegrityError(f"{MANIFEST}: not JSON ({exc})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise IntegrityError(f"{MANIFEST}: no file list")
    verify_files(manifest, contents)
    return manifest, contents, signature


def _env_file(config: dict[str, Any], target: Path, python: str) -> str:
    values = {
        "RASM_UNIT": config["unit"],
        "RASM_ROLE": config["role"],
        "RASM_TRANSPORT": config["transport"],
        "RASM_CLOCK": config["clock"],
        "RASM_KNOWLEDGE": config["knowledge"],
        "RASM_APP_MODULE": config["app_module"],
        "RASM_APP_DIST": config["app_dist"],
        "RASM_PLATFORM_TAG": config["binaries"].rpartition("/")[2],
        "RASM_DIR": str(target),
        "RASM_PACKAGE_DIR": str(target / "package"),
        "RASM_VENV": str(target / "venv"),
        "RASM_PYTHON": python,
        # the unit's flight recorder: rasm run --trace, rotated by size (at most 5 x 64 MB)
        "RASM_TRACE": str(target / "run" / "trace.jsonl"),
        "RASM_TRACE_ROTATE": "64M",
        "RASM_TRACE_KEEP": "4",
    }
    lines = [f': "${{{k}:={shlex.quote(str(v))}}}"' for k, v in values.items()]
    lines += [f"export {k}" for k in values]
    return (
        "# written by rasm deploy: the unit's settings for 05_Actions/*.sh\n"
        + "\n".join(lines)
        + "\n"
    )


def _alive(pid: str) -> bool:
    try:
        os.kill(int(pid), 0)
    except (ValueError, ProcessLookupError):
        return False
    except PermissionError:
        return True
    return True


def run_workflow(target: Path, name: str, env: dict[str, str] | None = None) -> list[StepResult]:
    """Run the workflow ``name`` of a deployed unit, stopping at the first failed action."""
    package = target / "package"
    spec = yaml.safe_load((package / "06_Workflows" / "workflows.yaml").read_text("utf-8"))
    workflow = spec["workflows"].get(name)
    if workflow is None:
        raise DeployError(f"no workflow '{name}' (have: {', '.join(sorted(spec['workflows']))})")
    results = []
    for action in workflow["steps"]:
        script = package / spec["actions"][action]
        done = subprocess.run(
            ["sh", str(script)],
            capture_output=True,
            text=True,
            env={**os.environ, **(env or {}), "RASM_DIR": str(target)},
            cwd=target,
        )
        results.append(StepResult(action, done.returncode, done.stdout + done.stderr))
        if done.returncode != 0:
            break
    return results


def deploy_package(
    package: str | Path,
    unit: str,
    target: str | Path,
    *,
    key: bytes | None = None,
    start: bool = False,
    python: str | None = None,
    env: dict[str, str] | None = None,
) -> DeployReport:
    """Verify ``package`` and deploy its compute unit ``unit`` into ``target``."""
    manifest, contents, signature = read_package(package, key)
    platform_file = f"04_Platform/{unit}.yaml"
    if platform_file not in contents:
        units = ", ".join(manifest.get("units", [])) or "none"
        raise DeployError(f"the package has no compute unit '{unit}' (units: {units})")
    config = yaml.safe_load(contents[platform_file])
    if config["arch"] != host_arch():
        raise DeployError(
            f"unit '{unit}' is {config['arch']} but this machine is {host_arch()}: deploy it "
            "on its own hardware"
        )
    target = Path(target).resolve()
    pidfile = target / "run" / f"{unit}.pid"
    if pidfile.is_file() and _alive(pidfile.read_text().strip()):
        raise DeployError(
            f"unit '{unit}' is running in {target} (pid {pidfile.read_text().strip()}): stop it "
            f"first (RASM_DIR={target} sh {target}/package/05_Actions/stop.sh)"
        )
    extracted = target / "package"
    if extracted.exists():
        shutil.rmtree(extracted)
    for name, data in contents.items():
        out = extracted / name
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(data)
        if name.endswith(".sh"):
            out.chmod(0o755)
    if (target / "venv").exists():
        shutil.rmtree(target / "venv")
    (target / "unit.env").write_text(
        _env_file(config, target, python or sys.executable), encoding="utf-8"
    )
    report = DeployReport(target, unit, config["role"], len(contents), signature)
    report.steps = run_workflow(target, "deploy", env)
    if report.ok and start:
        report.steps += run_workflow(target, "start", env)
    return report
