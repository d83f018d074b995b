"""``rasm deploy``: verify a package, install one compute unit from it, validate, start.

Nothing is written before the whole package is verified: every file's SHA-256 against
``MANIFEST.json``, no file missing or unlisted, the HMAC-SHA256 signature when a key is
configured, every entry's path (inside the package, in plain form, no file where another entry
needs a folder), the unit's configuration and the workflows with the actions they name. Then
the package is extracted to ``DIR/package``, the unit's
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

from rasm.errors import RasmError, SourceError, not_utf8
from rasm.workflow.derive import host_arch
from rasm.workflow.integrity import (
    MANIFEST,
    SIGNATURE,
    IntegrityError,
    shown,
    verify_files,
    verify_signature,
)
from rasm.yamltext import load_yaml, plain

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


# what 04_Platform/<unit>.yaml must give (written by rasm package), each a non-empty string
_UNIT_KEYS = (
    "unit", "arch", "role", "transport", "clock", "knowledge", "app_module", "app_dist",
    "binaries",
)
_NAME_BYTES = 255  # the longest file or folder name Linux file systems take


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


def _check_entry(name: str) -> None:
    """Refuse an entry name that could write outside the package folder, or that names one file
    in two ways (``a//b``, ``./a``): extraction writes exactly the names verified."""
    path = PurePosixPath(name)
    if path.is_absolute() or ".." in path.parts or "\\" in name:
        raise IntegrityError(f"{shown(name)}: a path outside the package")
    if str(path) != name or name in ("", "."):
        raise IntegrityError(f"{name!r}: not a plain relative path (write {str(path)!r})")
    if any(ord(c) < 32 or c == "\x7f" for c in name):
        raise IntegrityError(f"{name!r}: a control character in a file name")
    if any(len(part.encode("utf-8", "surrogateescape")) > _NAME_BYTES for part in path.parts):
        raise IntegrityError(f"{shown(name[:60])}...: a name longer than {_NAME_BYTES} bytes")


def _check_layout(names: list[str]) -> None:
    """Refuse a file that is also a folder of another entry (``X`` and ``X/file``): extraction
    would fail half-way, after writing."""
    folders = {str(parent) for name in names for parent in PurePosixPath(name).parents}
    for name in sorted(names):
        if name in folders:
            inside = next(n for n in sorted(names) if n.startswith(name + "/"))
            raise IntegrityError(f"{shown(name)}: both a file and the folder of {shown(inside)}")


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
                _check_entry(info.filename)
                if info.filename in contents:
                    raise IntegrityError(f"{shown(info.filename)}: appears twice in the package")
                contents[info.filename] = archive.read(info)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError) as exc:
        raise IntegrityError(f"{path}: not a package (bad zip: {exc})") from None
    except FileNotFoundError:
        raise IntegrityError(f"{path}: no such package") from None
    except IsADirectoryError:
        raise IntegrityError(f"{path}: a folder, not a package") from None
    except (ValueError, RuntimeError) as exc:  # an encrypted entry, a bad compression header
        raise IntegrityError(f"{path}: not a package ({exc})") from None
    if MANIFEST not in contents:
        raise IntegrityError(f"{path}: no {MANIFEST}: not a rasm package")
    raw = contents[MANIFEST]
    signature = verify_signature(raw, contents.get(SIGNATURE), key)
    try:
        manifest = json.loads(raw)
    except (ValueError, RecursionError) as exc:  # not JSON, not UTF-8, nested too deep
        raise IntegrityError(f"{MANIFEST}: not JSON ({exc})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise IntegrityError(f"{MANIFEST}: no file list")
    verify_files(manifest, contents)
    _check_layout(list(contents))
    return manifest, contents, signature


def _yaml_file(contents: dict[str, bytes], name: str) -> Any:
    try:
        text = contents[name].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DeployError(str(not_utf8(name, exc))) from None
    try:
        return plain(load_yaml(text, name).data)
    except SourceError as error:
        raise DeployError(f"{error.location}: {error.message}") from None


def _unit_config(contents: dict[str, bytes], name: str) -> dict[str, Any]:
    """The unit's configuration, every key deploy uses present as a non-empty string."""
    config = _yaml_file(contents, name)
    if not isinstance(config, dict):
        raise DeployError(f"{name}: a unit's configuration is a mapping")
    for key in _UNIT_KEYS:
        if not isinstance(config.get(key), str) or not config[key]:
            raise DeployError(f"{name}: '{key}' must be a non-empty string")
    return config


def _workflows(spec: Any, where: str, files: set[str] | None = None) -> dict[str, Any]:
    """``workflows.yaml`` checked: each workflow's steps name actions, each action a script
    (one of ``files`` when given: the package's)."""
    if not isinstance(spec, dict):
        raise DeployError(f"{where}: a mapping with 'workflows' and 'actions'")
    workflows, actions = spec.get("workflows"), spec.get("actions")
    if not isinstance(workflows, dict) or not isinstance(actions, dict):
        raise DeployError(f"{where}: 'workflows' and 'actions' must be mappings")
    for name, workflow in workflows.items():
        steps = workflow.get("steps") if isinstance(workflow, dict) else None
        if not isinstance(steps, list):
            raise DeployError(f"{where}: workflow '{name}' needs a list of 'steps'")
        for step in steps:
            if not isinstance(step, str) or step not in actions:
                raise DeployError(f"{where}: workflow '{name}': {step!r} is not an action")
    for name, script in actions.items():
        if not isinstance(script, str) or (files is not None and script not in files):
            raise DeployError(f"{where}: action '{name}': {script!r} is not a file of the package")
    return spec


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
    file = package / "06_Workflows" / "workflows.yaml"
    try:
        spec = _workflows(plain(load_yaml(file.read_text("utf-8"), str(file)).data), str(file))
    except (OSError, UnicodeDecodeError, SourceError) as exc:
        raise DeployError(f"{file}: cannot read the workflows: {exc}") from None
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
    """Verify ``package`` and deploy its compute unit ``unit`` into ``target``.

    Everything is verified before anything is written: a refused package leaves ``target``
    as it was."""
    manifest, contents, signature = read_package(package, key)
    platform_file = f"04_Platform/{unit}.yaml"
    if platform_file not in contents:
        listed = manifest.get("units")
        units = ", ".join(map(str, listed)) if isinstance(listed, list) and listed else "none"
        raise DeployError(f"the package has no compute unit '{unit}' (units: {units})")
    config = _unit_config(contents, platform_file)
    workflows_file = "06_Workflows/workflows.yaml"
    if workflows_file not in contents:
        raise DeployError(f"the package has no {workflows_file}")
    spec = _workflows(_yaml_file(contents, workflows_file), workflows_file, set(contents))
    for needed in ("deploy", "start") if start else ("deploy",):
        if needed not in spec["workflows"]:
            raise DeployError(f"{workflows_file}: no workflow '{needed}'")
    if config["arch"] != host_arch():
        raise DeployError(
            f"unit '{unit}' is {config['arch']} but this machine is {host_arch()}: deploy it "
            "on its own hardware"
        )
    target = Path(target).resolve()
    if target.exists() and not target.is_dir():
        raise DeployError(f"{target}: not a folder")
    pidfile = target / "run" / f"{unit}.pid"
    if pidfile.is_file() and _alive(pidfile.read_text().strip()):
        raise DeployError(
            f"unit '{unit}' is running in {target} (pid {pidfile.read_text().strip()}): stop it "
            f"first (RASM_DIR={target} sh {target}/package/05_Actions/stop.sh)"
        )
    extracted = target / "package"
    if extracted.is_dir() and not extracted.is_symlink():
        shutil.rmtree(extracted)
    elif extracted.exists() or extracted.is_symlink():  # never write through a link
        extracted.unlink()
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
