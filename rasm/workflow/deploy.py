"""``rasm deploy``: verify a package, install one compute unit from it, validate, start.

Nothing is written before the whole package is verified, with bounded memory
(:mod:`rasm.workflow.unpack`): every entry's path (inside the package, in plain form, no file
where another entry needs a folder), the HMAC-SHA256 signature when a key is configured, the
sizes the zip declares (no zip bomb) against those ``MANIFEST.json`` declares, no file missing
or unlisted, every file's SHA-256 (streamed), the unit's configuration and the workflows with the
actions they name. Then the package is extracted to ``DIR/package`` (streamed, re-hashed), the
unit's
variables are written to ``DIR/unit.env``, and the workflow ``deploy`` of
``06_Workflows/workflows.yaml`` runs its actions (``05_Actions/*.sh``): install from
``01_Binaries`` into ``DIR/venv`` with ``pip --no-index``, then validate. ``start=True`` also runs
the workflow ``start`` (the unit's nodes in the background).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import RasmError, SourceError, not_utf8
from rasm.workflow.derive import host_arch
from rasm.workflow.unpack import Package, open_package
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


def read_package(package: str | Path, key: bytes | None) -> Package:
    """The verified package: signature, file list, sizes and checksums checked with bounded
    memory (:mod:`rasm.workflow.unpack`); raises :class:`IntegrityError`."""
    return open_package(package, key)


def _yaml_file(package: Package, name: str) -> Any:
    try:
        text = package.read(name).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DeployError(str(not_utf8(name, exc))) from None
    try:
        return plain(load_yaml(text, name).data)
    except SourceError as error:
        raise DeployError(f"{error.location}: {error.message}") from None


def _unit_config(package: Package, name: str) -> dict[str, Any]:
    """The unit's configuration, every key deploy uses present as a non-empty string."""
    config = _yaml_file(package, name)
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
    verified = read_package(package, key)
    contents = verified.entries
    platform_file = f"04_Platform/{unit}.yaml"
    if platform_file not in contents:
        listed = verified.manifest.get("units")
        units = ", ".join(map(str, listed)) if isinstance(listed, list) and listed else "none"
        raise DeployError(f"the package has no compute unit '{unit}' (units: {units})")
    config = _unit_config(verified, platform_file)
    workflows_file = "06_Workflows/workflows.yaml"
    if workflows_file not in contents:
        raise DeployError(f"the package has no {workflows_file}")
    spec = _workflows(_yaml_file(verified, workflows_file), workflows_file, set(contents))
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
    verified.extract(extracted)
    if (target / "venv").exists():
        shutil.rmtree(target / "venv")
    (target / "unit.env").write_text(
        _env_file(config, target, python or sys.executable), encoding="utf-8"
    )
    report = DeployReport(target, unit, config["role"], len(contents), verified.signature)
    report.steps = run_workflow(target, "deploy", env)
    if report.ok and start:
        report.steps += run_workflow(target, "start", env)
    return report
